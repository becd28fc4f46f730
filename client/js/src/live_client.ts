// One avatar (the JavaScript twin of the C++ LiveClient,
// client/include/sweptccd_client/live_client.h): joins with its skeleton,
// publishes poses, hears its contact events, shared-world contacts,
// rejections and status, leaves; when the connection drops it reconnects
// with backoff and joins again (the new session's seq restarts at 0).

import { Connection, ConnectionEvents, ConnectionOptions, FatalError } from "./connection.js";
import { escapeForDisplay } from "./codec.js";
import {
  ContactEvent,
  EntityIgnore,
  Hello,
  JoinReply,
  JoinRequest,
  MOTION,
  Quat,
  REASON,
  Rejection,
  ServerMessage,
  SharedContact,
  SkeletonArrays,
  Status,
  TrackerPose,
  Vec3,
} from "./protocol.js";
import { SkeletonFile, skeletonToArrays } from "./skeleton.js";

const CLIENT_ID = /^[A-Za-z0-9_.-]{1,64}$/;

export interface LiveClientOptions extends ConnectionOptions {
  /** 1-64 of [A-Za-z0-9_.-]. */
  clientId: string;
  /** A SPEC section 1 skeleton, or its join arrays. */
  skeleton: SkeletonFile | SkeletonArrays;
  /** MOTION.ARTICULATED (default) or MOTION.INDEPENDENT. */
  motion?: number;
  /** Tolerances; 0: the daemon's. */
  epsS?: number;
  deltaM?: number;
  /** LINK:OBJECT rules (as `sweptccd query --ignore`). */
  ignore?: string[];
  /** Shared-world filters (SPEC 8 "Filters"). */
  ignoreEntities?: EntityIgnore[];
  /** Random per instance when absent (a safe integer). */
  nonce?: number;
  /** Poses are dropped (latest wins) while more than this many bytes wait to be sent. Default 1 MiB. */
  maxBufferedBytes?: number;
}

export interface JoinedInfo {
  reply: JoinReply;
  /** true for every join after the first (a reconnect). */
  rejoin: boolean;
}

export interface LiveClientEvents extends ConnectionEvents {
  joined: JoinedInfo;
  /** A refused join (reason, reason_name, message). */
  refused: JoinReply;
  contact: ContactEvent;
  sharedContact: SharedContact;
  rejection: Rejection;
  status: Status;
}

/** A refused join: the join_reply says why. */
export class JoinRefusedError extends FatalError {
  constructor(readonly reply: JoinReply) {
    super(
      `join refused: ${reply.reason_name ?? reply.reason}: ${escapeForDisplay(reply.message ?? "")}`,
      reply.reason_name ?? `reason_${reply.reason}`,
    );
    this.name = "JoinRefusedError";
  }
}

/** Refusals worth trying again after a backoff (the room may change). */
const RETRY_REASONS = new Set<number>([REASON.BUSY, REASON.TOO_MANY_CLIENTS, REASON.STALE_REQUEST]);

/** What publishPose takes: utime (default: now, strictly increasing), seq (default: the next). */
export interface PoseInput {
  position: Vec3[];
  orientation: Quat[];
  utime?: number;
  seq?: number;
}

export class LiveClient extends Connection<LiveClientEvents> {
  readonly clientId: string;
  readonly skeleton: SkeletonArrays;
  private readonly live: Required<Pick<LiveClientOptions, "motion" | "epsS" | "deltaM" | "ignore" | "ignoreEntities" | "nonce" | "maxBufferedBytes">>;
  private sessionValue = 0;
  private joinedValue = false;
  private joins = 0;
  private seq = 0;
  private lastUtime = 0;
  /** Poses not sent: not joined, or the send buffer was full. */
  droppedPoses = 0;
  /** Poses sent. */
  sentPoses = 0;

  constructor(options: LiveClientOptions) {
    super(options);
    if (!CLIENT_ID.test(options.clientId)) throw new Error("clientId: 1-64 of [A-Za-z0-9_.-]");
    this.clientId = options.clientId;
    const sk = options.skeleton as SkeletonFile & SkeletonArrays;
    this.skeleton = Array.isArray(sk.links) ? skeletonToArrays(sk) : sk;
    if (!Array.isArray(this.skeleton.link_name) || this.skeleton.link_name.length === 0) throw new Error("skeleton: no links");
    this.live = {
      motion: options.motion ?? MOTION.ARTICULATED,
      epsS: options.epsS ?? 0,
      deltaM: options.deltaM ?? 0,
      ignore: options.ignore ?? [],
      ignoreEntities: options.ignoreEntities ?? [],
      nonce: options.nonce ?? Math.floor(Math.random() * Number.MAX_SAFE_INTEGER),
      maxBufferedBytes: options.maxBufferedBytes ?? 1 << 20,
    };
  }

  get joined(): boolean {
    return this.joinedValue;
  }
  get session(): number {
    return this.sessionValue;
  }
  get nonce(): number {
    return this.live.nonce;
  }
  /** Joins after the first (reconnects that joined again). */
  get rejoins(): number {
    return Math.max(0, this.joins - 1);
  }

  /** The join_request this client sends (proof filled in on the wire). */
  joinRequest(proof: string): JoinRequest {
    const e = this.live.ignoreEntities;
    return {
      type: "join_request",
      utime: Date.now() * 1000,
      client_id: this.clientId,
      nonce: this.live.nonce,
      motion: this.live.motion,
      eps_s: this.live.epsS,
      delta_m: this.live.deltaM,
      link_name: this.skeleton.link_name,
      parent: this.skeleton.parent,
      a: this.skeleton.a,
      b: this.skeleton.b,
      radius: this.skeleton.radius,
      ignore: this.live.ignore,
      ignore_entity_link: e.map((r) => r.link),
      ignore_entity: e.map((r) => r.entity),
      ignore_entity_other_link: e.map((r) => r.other_link ?? ""),
      proof,
    };
  }

  /**
   * Sends one pose of every link (world frame, link index order). False
   * when not joined, the link count is wrong or the send buffer is full
   * (the pose is dropped: a newer one will follow).
   */
  publishPose(pose: PoseInput): boolean {
    const n = this.skeleton.link_name.length;
    if (pose.position.length !== n || pose.orientation.length !== n) {
      throw new Error(`pose: ${pose.position.length} positions / ${pose.orientation.length} orientations, the skeleton has ${n} links`);
    }
    if (!this.joinedValue || this.bufferedAmount() > this.live.maxBufferedBytes) {
      this.droppedPoses++;
      return false;
    }
    const utime = pose.utime ?? Math.max(Date.now() * 1000, this.lastUtime + 1);
    const seq = pose.seq ?? this.seq;
    const msg: TrackerPose = {
      type: "tracker_pose",
      utime,
      client_id: this.clientId,
      session: this.sessionValue,
      seq,
      position: pose.position,
      orientation: pose.orientation,
    };
    if (!this.sendMessage(msg)) {
      this.droppedPoses++;
      return false;
    }
    this.seq = seq + 1;
    this.lastUtime = utime;
    this.sentPoses++;
    return true;
  }

  /** Ends the session (a leave message), then closes. Idempotent. */
  leave(): void {
    if (this.joinedValue) {
      this.sendMessage({ type: "leave", utime: Date.now() * 1000, client_id: this.clientId, session: this.sessionValue });
    }
    this.joinedValue = false;
    this.close(1000, "leave");
  }

  protected async onHello(_hello: Hello): Promise<void> {
    const proof = await this.proof("join", this.clientId);
    this.sendMessage(this.joinRequest(proof));
  }

  protected onDrop(): void {
    this.joinedValue = false;
  }

  protected onMessage(msg: ServerMessage): void {
    switch (msg.type) {
      case "join_reply":
        return this.onJoinReply(msg);
      case "contact_event":
        if (msg.client_id === this.clientId) this.emit("contact", msg);
        return;
      case "shared_contact":
        this.emit("sharedContact", msg);
        return;
      case "rejection":
        this.emit("rejection", msg);
        // The service dropped this session (silent for silence_timeout_ms):
        // join again on a new connection (docs/WEBSOCKET.md section 3).
        if (msg.client_id === this.clientId && (msg.reason === "unknown_client" || msg.reason === "stale_session") && this.joinedValue) {
          this.restart(`the service forgot this session (${msg.reason}); joining again`);
        }
        return;
      case "status":
        this.emit("status", msg);
        return;
      default:
        this.emit("protocolError", `unexpected ${msg.type} for a live client: ignored`);
    }
  }

  private onJoinReply(reply: JoinReply): void {
    if (reply.client_id !== this.clientId || reply.nonce !== this.live.nonce) {
      this.emit("protocolError", "a join_reply for another join: ignored");
      return;
    }
    if (this.joinedValue) {
      this.emit("protocolError", "a second join_reply: ignored");
      return;
    }
    if (reply.reason !== REASON.ACCEPTED) {
      this.emit("refused", reply);
      if (RETRY_REASONS.has(reply.reason)) this.restart(`join refused (${reply.reason_name ?? reply.reason}); trying again`);
      else this.fail(new JoinRefusedError(reply));
      return;
    }
    this.sessionValue = reply.session;
    this.joinedValue = true;
    this.seq = 0;
    this.lastUtime = 0;
    this.joins++;
    this.markReady();
    this.emit("joined", { reply, rejoin: this.joins > 1 });
  }
}
