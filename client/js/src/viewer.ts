// A viewer (subscriber): the live view and operator tools. It proves the
// room key (unsigned mode: nothing), then hears the room snapshot, every
// client's poses (latest-wins per id), every contact, shared contact,
// rejection and status. Reconnects and subscribes again by itself.

import { Connection, ConnectionEvents, ConnectionOptions } from "./connection.js";
import { ContactEvent, Hello, ObjectPose, Rejection, Room, ServerMessage, SharedContact, Status, TrackerPose } from "./protocol.js";

export interface ViewerEvents extends ConnectionEvents {
  room: Room;
  pose: TrackerPose;
  objectPose: ObjectPose;
  contact: ContactEvent;
  sharedContact: SharedContact;
  rejection: Rejection;
  status: Status;
}

export class Viewer extends Connection<ViewerEvents> {
  /** The last room snapshot. */
  room: Room | null = null;

  constructor(options: ConnectionOptions) {
    super(options);
  }

  protected async onHello(_hello: Hello): Promise<void> {
    const proof = await this.proof("subscribe", "");
    this.sendMessage({ type: "subscribe", proof });
  }

  protected onMessage(msg: ServerMessage): void {
    switch (msg.type) {
      case "room":
        this.room = msg;
        if (this.state !== "ready") this.markReady();
        this.emit("room", msg);
        return;
      case "tracker_pose":
        this.emit("pose", msg);
        return;
      case "object_pose":
        this.emit("objectPose", msg);
        return;
      case "contact_event":
        this.emit("contact", msg);
        return;
      case "shared_contact":
        this.emit("sharedContact", msg);
        return;
      case "rejection":
        this.emit("rejection", msg);
        return;
      case "status":
        this.emit("status", msg);
        return;
      default:
        return;
    }
  }
}
