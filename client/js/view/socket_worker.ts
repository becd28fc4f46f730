// The live view's connection, off the page's main thread: a Web Worker holds
// the Viewer (socket, JSON decoding, checks) and keeps only the latest pose
// per client and per object; the page asks once per animation frame and gets
// them in one message. Room, contacts, status and errors go on at once.
//   page -> worker: {kind: "start", url, key} | {kind: "frame"}
//   worker -> page: {kind: "event", name, value} | {kind: "poses", poses, objects, received}
//                 | {kind: "failed", message, code}

import { ObjectPose, TrackerPose, Viewer } from "../src/index.js";

const post = (m: unknown) => (self as unknown as { postMessage(m: unknown): void }).postMessage(m);
const latest = new Map<string, TrackerPose>();
const latestObjects = new Map<string, ObjectPose>();
let received = 0;
let viewer: Viewer | null = null;

self.onmessage = (ev: MessageEvent) => {
  const m = ev.data as { kind: string; url?: string; key?: string };
  if (m.kind === "start" && !viewer && typeof m.url === "string") {
    const v = new Viewer({ url: m.url, key: m.key || undefined });
    viewer = v;
    for (const name of ["state", "hello", "room", "contact", "sharedContact", "status", "serverError", "protocolError"] as const) {
      v.on(name, (value: unknown) => post({ kind: "event", name, value }));
    }
    v.on("pose", (p) => {
      received++;
      latest.set(p.client_id, p);
    });
    v.on("objectPose", (p) => latestObjects.set(p.object_id, p));
    v.connect().catch((e: Error & { code?: string }) => post({ kind: "failed", message: String(e.message), code: e.code ?? "" }));
  } else if (m.kind === "frame") {
    post({ kind: "poses", poses: [...latest.values()], objects: [...latestObjects.values()], received });
    latest.clear();
    latestObjects.clear();
  }
};
