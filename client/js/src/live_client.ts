// One avatar (the JavaScript twin of the C++ LiveClient,
// client/include/sweptccd_client/live_client.h): joins with its skeleton,
// publishes poses, hears its contact events, shared-world contacts,
// rejections and status, leaves; when the connection drops it reconnects
// with backoff and joins again under a new session.
//
// Failover (docs/DEPLOY.md, docs/WEBSOCKET.md section 9), as the C++
// WsLiveClient: seq keeps counting across re-joins; no status of the joined
// instance for heartbeatTimeoutMs: the room is taken for dead and resolved
// again; poses whose pair is unanswered are re-sent after the re-join
// (lock-step, paced under the door's limits); an answer for a pair already
// delivered is dropped; events of another instance are fenced (Connection).

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
import { jointFrameToLinks } from "./joint_frame.js";
import type { JointFrameOptions, JointLinkRule, JointSample } from "./joint_frame.js";

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
  /** No status of the joined instance for this long: the room is dead, ms (0: never). Default 3000. */
  heartbeatTimeoutMs?: number;
  /** Unanswered poses kept for a re-join. Default 4096. */
  maxPendingPoses?: number;
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
  private readonly live: Required<Pick<LiveClientOptions, "motion" | "epsS" | "deltaM" | "ignore" | "ignoreEntities" | "nonce" | "maxBufferedBytes" | "heartbeatTimeoutMs" | "maxPendingPoses">>;
  /** Poses from the last answered one on (re-sent after a re-join). */
  private pending: TrackerPose[] = [];
  private answered = new Set<number>();
  private resend: TrackerPose[] = [];
  private awaiting = -1;
  private resendTimer: ReturnType<typeof setTimeout> | null = null;
  private heartbeat: ReturnType<typeof setInterval> | null = null;
  private lastStatusMs = 0;
  /** Failover counters. */
  heartbeatLosses = 0;
  resentPoses = 0;
  repeatedAnswers = 0;
  forgottenPoses = 0;
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
      heartbeatTimeoutMs: options.heartbeatTimeoutMs ?? 3000,
      maxPendingPoses: options.maxPendingPoses ?? 4096,
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
    const rejoining = !this.joinedValue && this.joins > 0 && this.state !== "closed";
    if ((!this.joinedValue && !rejoining) || this.bufferedAmount() > this.live.maxBufferedBytes) {
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
    if (seq < this.seq) {
      // Numbered from anew (a new stream): the old stream's poses and answers go.
      this.pending = [];
      this.answered.clear();
    }
    this.pending.push(msg);
    if (this.pending.length > this.live.maxPendingPoses) {
      this.pending.shift();
      this.forgottenPoses++;
    }
    this.seq = seq + 1;
    this.lastUtime = utime;
    if (rejoining) return true; // Sent after the re-join.
    if (this.resend.length > 0 || this.awaiting >= 0) {
      this.resend.push(msg); // Behind the re-sent ones.
      return true;
    }
    if (!this.sendMessage(msg)) {
      this.droppedPoses++;
      return false;
    }
    this.sentPoses++;
    return true;
  }

  /**
   * Publishes one frame of a tracking runtime's joint poses (WebXR, OpenXR,
   * VRM; docs/SKELETONS.md) as the link poses of the skeleton this client
   * joined with, `rules` being that skeleton's jointRulesOf: converts it
   * (jointFrameToLinks, the C++ rule's mirror) and publishes it as
   * publishPose does. Returns null when sent; else nothing is sent and the
   * one-line reason: the frame's problem (a joint a link needs not tracked,
   * NaN, a bone off its length), rules for another link count, or the pose
   * dropped (not joined, send buffer full). The C++ client's
   * PublishJointFrame and the Python client's publish_joints.
   */
  publishJoints(
    rules: JointLinkRule[],
    joints: Map<string, JointSample | null>,
    options: JointFrameOptions & { utime?: number; seq?: number } = {},
  ): string | null {
    const n = this.skeleton.link_name.length;
    if (rules.length !== n) return `joint frame: the joint rules have ${rules.length} links, this client joined with ${n}`;
    const frame = jointFrameToLinks(rules, joints, options);
    if ("error" in frame) return frame.error;
    const pose: PoseInput = {
      position: frame.links.map((l) => l[0]),
      orientation: frame.links.map((l) => l[1]),
      utime: options.utime,
      seq: options.seq,
    };
    return this.publishPose(pose) ? null : "not joined or the send buffer is full: the pose was dropped";
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
    this.resend = [];
    this.awaiting = -1;
    if (this.resendTimer) clearTimeout(this.resendTimer);
    this.resendTimer = null;
  }

  close(code = 1000, reason = "bye"): void {
    if (this.heartbeat) clearInterval(this.heartbeat);
    this.heartbeat = null;
    if (this.resendTimer) clearTimeout(this.resendTimer);
    this.resendTimer = null;
    super.close(code, reason);
  }

  // Re-sent poses go one pair at a time (the service's latest-wins would
  // merge a burst into one pair), no faster than 80 % of the door's limits.
  private pump(): void {
    if (this.awaiting >= 0 || this.resendTimer || this.resend.length === 0 || !this.joinedValue) return;
    const msg = { ...this.resend.shift()!, session: this.sessionValue };
    if (this.sendMessage(msg)) this.sentPoses++;
    const limits = this.hello?.limits;
    const rate = 0.8 * Math.min(limits?.message_rate_hz ?? 480, limits?.max_pose_rate_hz ?? 240);
    this.resendTimer = setTimeout(() => {
      this.resendTimer = null;
      this.pump();
    }, 1000 / Math.max(rate, 1));
    {
      this.awaiting = msg.seq;
      setTimeout(() => {
        if (this.awaiting === msg.seq) {
          this.awaiting = -1; // No answer (shed): go on.
          this.pump();
        }
      }, 250);
    }
  }

  private pumpFirst(): void {
    // The first re-sent pose anchors the new session's stream: no pair.
    const first = { ...this.resend.shift()!, session: this.sessionValue };
    if (this.sendMessage(first)) this.sentPoses++;
    this.pump();
  }

  private pairDone(seq: number): void {
    if (this.awaiting < 0 || seq < this.awaiting) return;
    this.awaiting = -1;
    this.pump();
  }

  /** The heartbeat timeout: at least 3 of the door's status periods (hello.limits.status_period_ms). */
  private heartbeatMs(): number {
    const period = this.hello?.limits?.status_period_ms;
    const told = typeof period === "number" && period > 0 && period <= 3600000 ? 3 * period : 0;
    return Math.max(this.live.heartbeatTimeoutMs, told);
  }

  private startHeartbeat(): void {
    if (this.heartbeat || !(this.live.heartbeatTimeoutMs > 0)) return;
    this.heartbeat = setInterval(() => {
      const ms = this.heartbeatMs();
      if (this.joinedValue && Date.now() - this.lastStatusMs > ms) {
        this.heartbeatLosses++;
        this.restart(`no status for ${ms} ms: room taken for dead`);
      }
    }, Math.max(10, this.live.heartbeatTimeoutMs / 8));
  }

  protected onMessage(msg: ServerMessage): void {
    switch (msg.type) {
      case "join_reply":
        return this.onJoinReply(msg);
      case "contact_event":
        if (msg.client_id !== this.clientId) return;
        this.pairDone(msg.seq1);
        while (this.pending.length > 0 && this.pending[0].seq < msg.seq1) this.pending.shift();
        if (this.answered.has(msg.seq1)) {
          this.repeatedAnswers++; // Answered before the re-join: not twice.
          return;
        }
        this.answered.add(msg.seq1);
        if (this.answered.size > 8192) this.answered.delete(this.answered.values().next().value as number);
        this.emit("contact", msg);
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
        } else if (msg.client_id === this.clientId) {
          this.pending = this.pending.filter((p) => p.seq !== msg.seq);
          this.pairDone(msg.seq);
        }
        return;
      case "status":
        this.lastStatusMs = Date.now();
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
    this.maxInstance = Math.max(this.maxInstance, reply.instance);
    this.lastStatusMs = Date.now();
    this.joins++;
    this.markReady();
    this.startHeartbeat();
    this.emit("joined", { reply, rejoin: this.joins > 1 });
    // The unanswered poses again, same seq and utime, under the new session.
    this.resend = this.pending.slice();
    this.resentPoses = 0;
    if (this.resend.length > 0) {
      this.resentPoses = this.resend.length;
      this.awaiting = -1;
      this.pumpFirst();
    }
  }
}
