// One tracked object's pose source (docs/WEBSOCKET.md section 6,
// object_attach / object_pose): proves the object's key (or the room key),
// then publishes the object's world pose. Objects are configured in the
// daemon (id, mesh), never joined. Reconnects and attaches again by itself,
// each time in a new, greater session (so seq and utime may restart).

import { Connection, ConnectionEvents, ConnectionOptions, FatalError } from "./connection.js";
import { escapeForDisplay } from "./codec.js";
import { Hello, ObjectAttachReply, ObjectPose, Quat, ServerMessage, Vec3 } from "./protocol.js";

const OBJECT_ID = /^[A-Za-z0-9_.-]{1,64}$/;

export interface ObjectTrackerOptions extends ConnectionOptions {
  /** A configured tracked object's id. */
  objectId: string;
}

export interface ObjectTrackerEvents extends ConnectionEvents {
  attached: ObjectAttachReply;
}

export class ObjectTracker extends Connection<ObjectTrackerEvents> {
  readonly objectId: string;
  private attachedValue = false;
  private sessionValue = 0;
  private seq = 0;
  private lastUtime = 0;
  sentPoses = 0;
  droppedPoses = 0;

  constructor(options: ObjectTrackerOptions) {
    super(options);
    if (!OBJECT_ID.test(options.objectId)) throw new Error("objectId: 1-64 of [A-Za-z0-9_.-]");
    this.objectId = options.objectId;
  }

  get attached(): boolean {
    return this.attachedValue;
  }
  get session(): number {
    return this.sessionValue;
  }

  /** The object's world pose (mesh frame); false when not attached. */
  publishPose(pose: { position: Vec3; orientation: Quat; utime?: number; seq?: number }): boolean {
    if (!this.attachedValue) {
      this.droppedPoses++;
      return false;
    }
    const utime = pose.utime ?? Math.max(Date.now() * 1000, this.lastUtime + 1);
    const seq = pose.seq ?? this.seq;
    const msg: ObjectPose = { type: "object_pose", utime, object_id: this.objectId, session: this.sessionValue, seq, position: pose.position, orientation: pose.orientation };
    if (!this.sendMessage(msg)) {
      this.droppedPoses++;
      return false;
    }
    this.seq = seq + 1;
    this.lastUtime = utime;
    this.sentPoses++;
    return true;
  }

  protected async onHello(_hello: Hello): Promise<void> {
    const proof = await this.proof("object_attach", this.objectId);
    this.sendMessage({ type: "object_attach", object_id: this.objectId, proof });
  }

  protected onDrop(): void {
    this.attachedValue = false;
  }

  protected onMessage(msg: ServerMessage): void {
    if (msg.type !== "object_attach_reply" || msg.object_id !== this.objectId || this.attachedValue) return;
    if (!msg.ok) {
      this.fail(new FatalError(`object_attach refused: ${escapeForDisplay(String(msg.message ?? ""))}`, "attach_refused"));
      return;
    }
    // A new stream each attach: greater than any before (microseconds now).
    this.sessionValue = Math.max(Date.now() * 1000, this.sessionValue + 1);
    this.seq = 0;
    this.lastUtime = 0;
    this.attachedValue = true;
    this.markReady();
    this.emit("attached", msg);
  }
}
