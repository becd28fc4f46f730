// @sweptccd/client: the JavaScript client of SweptCCD's WebSocket door
// (protocol sweptccd.v1, docs/WEBSOCKET.md). Browser-safe; in Node import
// "@sweptccd/client/node" (the `ws` package and node:crypto wired in).
export * from "./protocol.js";
export * from "./proof.js";
export * from "./codec.js";
export * from "./emitter.js";
export * from "./skeleton.js";
export * from "./connection.js";
export * from "./live_client.js";
export * from "./viewer.js";
export * from "./scene_mesh.js";
export * from "./pose_math.js";
export * from "./xr_skeleton.js";
export * from "./joint_frame.js";
export * from "./object_tracker.js";
export * from "./rooms.js";
