// Unit tests of the JavaScript client (client/js) under Node's test runner:
// the proofs against the worked example of docs/WEBSOCKET.md section 4, the
// checks on what a server sends, the skeleton and pose codecs, and the
// client's state machine (join, poses, reconnect with re-join, refusals,
// leave) against a stand-in server made with the `ws` package on loopback
// (the real daemon is tested in js_client_e2e.sh).
//   SWEPTCCD_JS_DIR=<build>/client/js node --test client_unit.test.mjs
import assert from "node:assert/strict";
import { createRequire } from "node:module";
import path from "node:path";
import { test } from "node:test";
import { pathToFileURL } from "node:url";

const jsDir = process.env.SWEPTCCD_JS_DIR;
if (!jsDir) throw new Error("set SWEPTCCD_JS_DIR to <build>/client/js");
const lib = await import(pathToFileURL(path.join(jsDir, "dist", "node.js")).href);
const require = createRequire(path.join(jsDir, "package.json"));
const { WebSocketServer } = require("ws");

const KEY = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
const CHALLENGE = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";

test("proofs equal the worked example of docs/WEBSOCKET.md", async () => {
  const key = lib.parseKey(KEY);
  const s = lib.nodeSubtle;
  assert.equal(
    await lib.makeProof(s, key, "join", CHALLENGE, "alice"),
    "e6bd9e779431f0b57eefbb0ff3014338726980284db0c9faa24c73edcfbbe43a",
  );
  assert.equal(
    await lib.makeProof(s, key, "subscribe", CHALLENGE, ""),
    "2be968d980c0efd035390f7580e7e47ee8712d12a5958cd6a1b0475285f22249",
  );
  assert.equal(
    await lib.makeProof(s, key, "object_attach", CHALLENGE, "ball"),
    "c4186d0519862a982fb5265688bcc74de86705923a38735cb8d8e4ea18a21e0a",
  );
  assert.equal(lib.proofText("join", CHALLENGE, "alice"), `sweptccd-ws-v1 join\n${CHALLENGE}\nalice`);
  // Another key or challenge: another proof.
  const other = lib.parseKey(KEY.replace(/^00/, "ff"));
  assert.notEqual(await lib.makeProof(s, other, "join", CHALLENGE, "alice"), "e6bd9e779431f0b57eefbb0ff3014338726980284db0c9faa24c73edcfbbe43a");
});

test("keys: 64 hex digits or 32 bytes, nothing else", () => {
  assert.equal(lib.parseKey(` ${KEY}\n`).length, 32);
  assert.equal(lib.parseKey(new Uint8Array(32)).length, 32);
  assert.throws(() => lib.parseKey(KEY.slice(2)), /64 hex/);
  assert.throws(() => lib.parseKey(KEY.replace("0", "g")), /64 hex/);
  assert.throws(() => lib.parseKey(new Uint8Array(31)), /32 bytes/);
  assert.throws(() => lib.hexToBytes("abc"), /hex/);
  assert.equal(lib.bytesToHex(lib.hexToBytes("00ff10")), "00ff10");
});

test("server messages are checked before use", () => {
  const hello = { type: "hello", protocol: 1, instance: 5, security: "signed", challenge: CHALLENGE, server_utime: 1 };
  assert.equal(lib.decodeServerMessage(JSON.stringify(hello)).challenge, CHALLENGE);
  const bad = (text, re, max) => assert.throws(() => lib.decodeServerMessage(text, max), (e) => e instanceof lib.DecodeError && re.test(e.message));
  bad("x".repeat(100), /over the cap/, 50);
  bad("{", /not JSON/);
  bad("[1]", /not a JSON object/);
  bad("null", /not a JSON object/);
  bad('{"a":1}', /no "type"/);
  bad('{"type":"launch_missiles\\u0007"}', /unknown type "launch_missiles\\x07"/);
  bad(JSON.stringify({ ...hello, challenge: "zz" }), /challenge/);
  bad(JSON.stringify({ ...hello, protocol: "1" }), /protocol/);
  bad(JSON.stringify({ type: "join_reply", client_id: "a", reason: 0, message: "", session: 1 }), /instance/);
  bad(JSON.stringify({ type: "contact_event", client_id: "a", seq0: 0, seq1: 1, pair: 0, result: 1, contacts: {} }), /contacts/);
  assert.throws(() => lib.decodeServerMessage(new Uint8Array(4)), /binary frame/);
  assert.equal(lib.escapeForDisplay("a\nb\u001b[31m\\"), "a\\x0ab\\x1b[31m\\\\");
});

test("skeletons become join arrays; bad ones are refused naming the link", () => {
  const sk = {
    links: [
      { name: "spine", parent: "pelvis", a: [0, 0, 0], b: [0, 0.3, 0], radius: 0.1 },
      { name: "pelvis", parent: null, a: [0, 0, 0], b: [0, 0.2, 0], radius: 0.12 },
    ],
  };
  const arr = lib.skeletonToArrays(sk);
  assert.deepEqual(arr.link_name, ["spine", "pelvis"]);
  assert.deepEqual(arr.parent, [1, -1]);
  assert.deepEqual(arr.b[0], [0, 0.3, 0]);
  assert.deepEqual(arr.radius, [0.1, 0.12]);
  const broken = (edit, re) => {
    const copy = JSON.parse(JSON.stringify(sk));
    edit(copy);
    assert.throws(() => lib.skeletonToArrays(copy), re);
  };
  broken((s) => (s.links[0].parent = "hip"), /"spine" has unknown parent "hip"/);
  broken((s) => (s.links[0].parent = null), /2 roots/);
  broken((s) => (s.links[1].radius = 0), /"pelvis" radius/);
  broken((s) => (s.links[1].name = "spine"), /duplicate/);
  broken((s) => (s.links[1].a = [0, NaN, 0]), /"pelvis" a/);
  broken((s) => s.links.push({ name: "x", parent: "y", a: [0, 0, 0], b: [0, 0, 0], radius: 1 }, { name: "y", parent: "x", a: [0, 0, 0], b: [0, 0, 0], radius: 1 }), /loop/);
  const poses = lib.parsePoseLines('{"utime": 5, "links": [[1,2,3,1,0,0,0],[4,5,6,0,1,0,0]]}\n\n{"utime": 6, "links": [[0,0,0,1,0,0,0],[0,0,0,1,0,0,0]]}\n');
  assert.equal(poses.length, 2);
  assert.deepEqual(poses[0].position[1], [4, 5, 6]);
  assert.deepEqual(poses[0].orientation[1], [0, 1, 0, 0]);
  assert.throws(() => lib.parsePoseLines('{"utime": 5, "links": [[1,2,3]]}'), /px,py,pz,qw/);
});

// A stand-in server on loopback: says hello with a fresh challenge, records
// what it receives, and answers as `answer` says.
async function standIn(answer, limits = { max_message_bytes: 262144 }) {
  const wss = new WebSocketServer({ host: "127.0.0.1", port: 0, handleProtocols: (p) => (p.has("sweptccd.v1") ? "sweptccd.v1" : false) });
  await new Promise((r) => wss.once("listening", r));
  const server = { received: [], sockets: [], challenges: [], targets: [], wss, url: `ws://127.0.0.1:${wss.address().port}/ws` };
  let n = 0;
  wss.on("connection", (sock, req) => {
    const challenge = (n++).toString(16).padStart(64, "a");
    server.sockets.push(sock);
    server.challenges.push(challenge);
    server.targets.push(req.url);
    sock.send(JSON.stringify({ type: "hello", protocol: 1, instance: 7, security: "signed", challenge, server_utime: Date.now() * 1000, room: "arcade-7", limits }));
    sock.on("message", (data) => {
      const msg = JSON.parse(String(data));
      server.received.push({ conn: server.sockets.indexOf(sock), challenge, msg });
      answer(sock, msg, server.sockets.indexOf(sock));
    });
  });
  server.close = () => new Promise((r) => { for (const s of server.sockets) s.terminate(); wss.close(r); });
  return server;
}

const SKELETON = { links: [{ name: "pelvis", parent: null, a: [0, 0, 0], b: [0, 0.2, 0], radius: 0.12 }, { name: "spine", parent: "pelvis", a: [0, 0, 0], b: [0, 0.3, 0], radius: 0.1 }] };
const POSE = { position: [[0, 1, 0], [0, 1.2, 0]], orientation: [[1, 0, 0, 0], [1, 0, 0, 0]] };
const accept = (sock, msg, session) =>
  sock.send(JSON.stringify({ type: "join_reply", utime: 1, client_id: msg.client_id, nonce: msg.nonce, reason: 0, reason_name: "accepted", message: "", session, instance: 7, silence_timeout_ms: 5000 }));
const until = async (what, ms = 3000) => {
  const t0 = Date.now();
  while (!what()) {
    if (Date.now() - t0 > ms) throw new Error("timed out");
    await new Promise((r) => setTimeout(r, 5));
  }
};

test("joins with a valid proof, streams poses, reconnects and joins again, leaves", async () => {
  const server = await standIn((sock, msg, conn) => {
    if (msg.type === "join_request") accept(sock, msg, 100 + conn);
  });
  const client = new lib.NodeLiveClient({ url: server.url, clientId: "alice", skeleton: SKELETON, key: KEY, backoffInitialMs: 20 });
  const joined = [];
  const contacts = [];
  client.on("joined", (j) => joined.push(j));
  client.on("contact", (c) => contacts.push(c));
  await client.connect();
  assert.equal(client.session, 100);
  const join = server.received[0].msg;
  assert.equal(join.type, "join_request");
  assert.deepEqual(join.link_name, ["pelvis", "spine"]);
  assert.deepEqual(join.parent, [-1, 0]);
  assert.equal(join.proof, await lib.makeProof(lib.nodeSubtle, lib.parseKey(KEY), "join", server.challenges[0], "alice"));
  assert.ok(Number.isSafeInteger(join.nonce));
  assert.equal(client.publishPose(POSE), true);
  assert.equal(client.publishPose(POSE), true);
  assert.throws(() => client.publishPose({ position: [[0, 0, 0]], orientation: [[1, 0, 0, 0]] }), /2 links/);
  await until(() => server.received.length === 3);
  const [p0, p1] = server.received.slice(1).map((r) => r.msg);
  assert.deepEqual([p0.seq, p1.seq, p0.session, p0.client_id], [0, 1, 100, "alice"]);
  assert.ok(p1.utime > p0.utime);
  // Events for this client arrive; a server's garbage is reported, not fatal.
  const garbage = [];
  client.on("protocolError", (e) => garbage.push(e));
  server.sockets[0].send("{nonsense");
  server.sockets[0].send(JSON.stringify({ type: "contact_event", client_id: "alice", seq0: 0, seq1: 1, pair: 0, result: 1, contacts: [] }));
  await until(() => contacts.length === 1);
  assert.equal(garbage.length, 1);
  // The connection drops: the client reconnects, proves again for the new
  // challenge with the same nonce; in the new session it first sends pose 1
  // again (the last answered one: it anchors the next pair), seq goes on.
  server.sockets[0].terminate();
  await until(() => joined.length === 2);
  const rejoin = server.received.find((r) => r.conn === 1).msg;
  assert.equal(rejoin.nonce, join.nonce);
  assert.equal(rejoin.proof, await lib.makeProof(lib.nodeSubtle, lib.parseKey(KEY), "join", server.challenges[1], "alice"));
  assert.equal(joined[1].rejoin, true);
  assert.equal(client.session, 101);
  assert.equal(client.rejoins, 1);
  assert.equal(client.publishPose(POSE), true);
  await until(() => server.received.some((r) => r.conn === 1 && r.msg.type === "tracker_pose"));
  await until(() => server.received.filter((r) => r.conn === 1 && r.msg.type === "tracker_pose").length === 2);
  assert.deepEqual(server.received.filter((r) => r.conn === 1 && r.msg.type === "tracker_pose").map((r) => [r.msg.seq, r.msg.session]), [[1, 101], [2, 101]]);
  client.leave();
  await until(() => server.received.some((r) => r.msg.type === "leave"));
  assert.deepEqual(server.received.find((r) => r.msg.type === "leave").msg.session, 101);
  assert.equal(client.state, "closed");
  assert.equal(client.publishPose(POSE), false);
  await server.close();
});

test("a refused join rejects connect() and is not retried; busy is", async () => {
  let busy = 1;
  const server = await standIn((sock, msg) => {
    if (msg.type !== "join_request") return;
    const reason = msg.client_id === "bob" && busy-- > 0 ? 8 : msg.client_id === "bob" ? 0 : 1;
    const names = { 0: "accepted", 1: "bad_skeleton", 8: "busy" };
    sock.send(JSON.stringify({ type: "join_reply", utime: 1, client_id: msg.client_id, nonce: msg.nonce, reason, reason_name: names[reason], message: "link 0: radius 0\u001b", session: reason ? 0 : 9, instance: 7, silence_timeout_ms: 5000 }));
  });
  const refused = new lib.NodeLiveClient({ url: server.url, clientId: "carol", skeleton: SKELETON, key: KEY, backoffInitialMs: 20 });
  await assert.rejects(refused.connect(), (e) => e instanceof lib.JoinRefusedError && e.code === "bad_skeleton" && /radius 0\\x1b/.test(e.message));
  await new Promise((r) => setTimeout(r, 100));
  assert.equal(server.received.filter((r) => r.msg.client_id === "carol").length, 1);
  const bob = new lib.NodeLiveClient({ url: server.url, clientId: "bob", skeleton: SKELETON, key: KEY, backoffInitialMs: 20 });
  await bob.connect();
  assert.equal(bob.session, 9);
  assert.equal(server.received.filter((r) => r.msg.client_id === "bob").length, 2);
  bob.close();
  await server.close();
});

test("bad_proof ends the client; a signed server without a key is refused locally", async () => {
  const server = await standIn((sock, msg) => {
    sock.send(JSON.stringify({ type: "error", code: "bad_proof", message: "the proof does not verify", fatal: true }));
    sock.close(1008, "bad_proof");
  });
  const c = new lib.NodeLiveClient({ url: server.url, clientId: "eve", skeleton: SKELETON, key: KEY.replace(/^00/, "11"), backoffInitialMs: 20 });
  await assert.rejects(c.connect(), (e) => e.code === "bad_proof");
  const keyless = new lib.NodeViewer({ url: server.url, backoffInitialMs: 20 });
  await assert.rejects(keyless.connect(), (e) => e.code === "no_key");
  await new Promise((r) => setTimeout(r, 100));
  assert.equal(server.sockets.length, 2); // Neither tried again.
  await server.close();
});

test("a viewer subscribes with the room key and hears the room", async () => {
  const server = await standIn((sock, msg) => {
    if (msg.type !== "subscribe") return;
    sock.send(JSON.stringify({ type: "room", clients: [{ client_id: "alice", link_name: ["x"], parent: [-1], a: [[0, 0, 0]], b: [[0, 0, 1]], radius: [0.1] }], objects: [], environment: ["room.obj"] }));
    sock.send(JSON.stringify({ type: "tracker_pose", utime: 1, client_id: "alice", session: 1, seq: 0, position: [[0, 0, 0]], orientation: [[1, 0, 0, 0]] }));
  });
  const v = new lib.NodeViewer({ url: server.url, key: KEY });
  const poses = [];
  v.on("pose", (p) => poses.push(p));
  await v.connect();
  assert.equal(v.room.clients[0].client_id, "alice");
  assert.equal(server.received[0].msg.proof, await lib.makeProof(lib.nodeSubtle, lib.parseKey(KEY), "subscribe", server.challenges[0], ""));
  await until(() => poses.length === 1);
  v.close();
  await server.close();
});

test("scene meshes (SCM1) are checked before anything is allocated", () => {
  const mesh = (v, t, edit) => {
    const buf = new ArrayBuffer(16 + 12 * v + 12 * t);
    const d = new DataView(buf);
    [..."SCM1"].forEach((c, i) => d.setUint8(i, c.charCodeAt(0)));
    d.setUint32(4, v, true);
    d.setUint32(8, t, true);
    for (let i = 0; i < 3 * v; i++) d.setFloat32(16 + 4 * i, i * 0.5, true);
    for (let i = 0; i < 3 * t; i++) d.setUint32(16 + 12 * v + 4 * i, i % v, true);
    if (edit) edit(d, buf);
    return buf;
  };
  const ok = lib.parseSceneMesh(mesh(3, 1));
  assert.deepEqual([...ok.positions], [0, 0.5, 1, 1.5, 2, 2.5, 3, 3.5, 4]);
  assert.deepEqual([...ok.indices], [0, 1, 2]);
  assert.throws(() => lib.parseSceneMesh(new ArrayBuffer(8)), /header/);
  assert.throws(() => lib.parseSceneMesh(mesh(3, 1, (d) => d.setUint8(3, 0x32))), /magic/);
  assert.throws(() => lib.parseSceneMesh(mesh(3, 1, (d) => d.setUint32(8, 2, true))), /header says/);
  assert.throws(() => lib.parseSceneMesh(mesh(3, 1, (d) => d.setUint32(4, 0xffffffff, true))), /over the caps/);
  assert.throws(() => lib.parseSceneMesh(mesh(3, 1, (d) => d.setUint32(16 + 36 + 8, 3, true))), /index 3 >= 3/);
  assert.throws(() => lib.parseSceneMesh(mesh(3, 1, (d) => d.setFloat32(20, NaN, true))), /not finite/);
  assert.throws(() => lib.parseSceneMesh(mesh(3, 1, (d) => d.setUint32(12, 1, true))), /reserved/);
});

test("link ends: p + R(q) a with q normalised", () => {
  const close = (a, b) => a.forEach((x, i) => assert.ok(Math.abs(x - b[i]) < 1e-12, `${a} vs ${b}`));
  // 90 degrees about z (not unit: scaled by 2) carries x to y.
  const s = Math.SQRT1_2 * 2;
  close(lib.rotate([s, 0, 0, s], [1, 0, 0]), [0, 1, 0]);
  close(lib.transformPoint([1, 2, 3], [s, 0, 0, s], [0, 0.5, 0]), [0.5, 2, 3]);
  // 180 degrees about x: y -> -y, z -> -z.
  close(lib.rotate([0, 1, 0, 0], [0, 1, 1]), [0, -1, -1]);
  close(lib.rotate([1, 0, 0, 0], [4, 5, 6]), [4, 5, 6]);
});

test("the WebXR skeleton: head, controllers, 25 joints per hand, held poses, y-up to z-up", () => {
  const id = [1, 0, 0, 0];
  const quarter = [Math.SQRT1_2, 0, Math.SQRT1_2, 0]; // 90 degrees about y: x -> -z
  const hand = new Map();
  lib.HAND_JOINTS.forEach((name, i) => hand.set(name, { position: [0.3, 1, -0.01 * i], orientation: name === "wrist" ? quarter : id, radius: 0.005 + i * 0.0001 }));
  const snap = { head: { position: [0, 1.6, 0], orientation: id }, controllers: { left: { position: [-0.3, 1, -0.2], orientation: id } }, hands: { right: hand } };
  const xs = lib.buildXrSkeleton(snap);
  assert.equal(xs.skeleton.links.length, 1 + 1 + 25);
  const arr = lib.skeletonToArrays(xs.skeleton); // a valid SPEC skeleton: one root, known parents, radii > 0
  assert.equal(arr.link_name[0], "head");
  assert.equal(arr.parent[0], -1);
  const wrist = arr.link_name.indexOf("right_wrist");
  assert.equal(arr.parent[wrist], 0);
  // The wrist's capsule reaches the middle finger's knuckle, in the wrist's frame.
  const knuckle = hand.get("middle-finger-phalanx-proximal").position;
  const reach = lib.transformPoint(hand.get("wrist").position, quarter, arr.b[wrist]);
  reach.forEach((x, i) => assert.ok(Math.abs(x - knuckle[i]) < 1e-12));
  assert.equal(arr.radius[wrist], 0.005);
  const tip = arr.link_name.indexOf("right_index-finger-tip");
  assert.deepEqual(arr.b[tip], [0, 0, 0]);
  assert.equal(arr.link_name[arr.parent[tip]], "right_index-finger-phalanx-distal");
  // Every link has a pose; a part lost later keeps its last one.
  const s0 = lib.xrSample(xs, snap, null);
  assert.equal(s0.length, 27);
  const lost = { ...snap, controllers: {}, head: { position: [0, 1.5, 0], orientation: id } };
  const s1 = lib.xrSample(xs, lost, s0);
  assert.deepEqual(s1[1].position, [-0.3, 1, -0.2]);
  assert.deepEqual(s1[0].position, [0, 1.5, 0]);
  assert.equal(lib.xrSample(xs, lost, null), null);
  assert.throws(() => lib.buildXrSkeleton({ head: null, controllers: {}, hands: {} }), /no head/);
  // WebXR's y-up into the room's z-up: up stays up, forward (-z) becomes +y; then the origin.
  const r = lib.xrToRoom({ position: [0, 1.6, -1], orientation: id }, [2, 3, 0], 0);
  [2, 4, 1.6].forEach((x, i) => assert.ok(Math.abs(r.position[i] - x) < 1e-12, `${r.position}`));
  const up = lib.rotate(r.orientation, [0, 1, 0]);
  [0, 0, 1].forEach((x, i) => assert.ok(Math.abs(up[i] - x) < 1e-12));
  const turned = lib.xrToRoom({ position: [0, 0, -1], orientation: id }, [0, 0, 0], Math.PI / 2);
  [-1, 0, 0].forEach((x, i) => assert.ok(Math.abs(turned.position[i] - x) < 1e-12, `${turned.position}`));
});

test("a tracked object attaches with its proof and streams object poses; a refusal is final", async () => {
  const server = await standIn((sock, msg) => {
    if (msg.type === "object_attach") sock.send(JSON.stringify({ type: "object_attach_reply", object_id: msg.object_id, ok: msg.object_id === "ball", message: msg.object_id === "ball" ? "" : "no tracked object 'cup'" }));
  });
  const ball = new lib.NodeObjectTracker({ url: server.url, key: KEY, objectId: "ball" });
  assert.equal(ball.publishPose({ position: [0, 0, 1], orientation: [1, 0, 0, 0] }), false);
  await ball.connect();
  const attach = server.received[0].msg;
  assert.equal(attach.proof, await lib.makeProof(lib.nodeSubtle, lib.parseKey(KEY), "object_attach", server.challenges[0], "ball"));
  assert.ok(ball.publishPose({ position: [0, 0, 1], orientation: [1, 0, 0, 0] }));
  assert.ok(ball.publishPose({ position: [0, 0, 1.1], orientation: [1, 0, 0, 0] }));
  await until(() => server.received.length === 3);
  const [p0, p1] = server.received.slice(1).map((r) => r.msg);
  assert.deepEqual([p0.type, p0.object_id, p0.seq, p1.seq, p0.session === ball.session], ["object_pose", "ball", 0, 1, true]);
  assert.deepEqual(p1.position, [0, 0, 1.1]);
  assert.ok(p1.utime > p0.utime);
  ball.close();
  const cup = new lib.NodeObjectTracker({ url: server.url, key: KEY, objectId: "cup" });
  await assert.rejects(cup.connect(), (e) => e.code === "attach_refused" && /no tracked object/.test(e.message));
  assert.throws(() => lib.decodeServerMessage('{"type":"object_attach_reply","object_id":"x","ok":"yes"}'), /ok/);
  await server.close();
});

test("keep-alive: a quiet connection pings every third of idle_timeout_ms; pong gives the round trip", async () => {
  const server = await standIn((sock, msg) => {
    if (msg.type === "subscribe") sock.send(JSON.stringify({ type: "room", clients: [], objects: [], environment: [] }));
    if (msg.type === "ping") sock.send(JSON.stringify({ type: "pong", utime: msg.utime, server_utime: Date.now() * 1000 }));
  }, { idle_timeout_ms: 300 });
  const v = new lib.NodeViewer({ url: server.url, key: KEY });
  const pongs = [];
  v.on("pong", (p) => pongs.push(p));
  await v.connect();
  await until(() => pongs.length >= 2, 3000);
  const pings = server.received.filter((r) => r.msg.type === "ping");
  assert.ok(pings.length >= 2 && Number.isSafeInteger(pings[0].msg.utime));
  assert.ok(pongs[0].roundTripMs >= 0 && pongs[0].roundTripMs < 1000);
  v.close();
  await server.close();
});

test("a session the service forgot (unknown_client) joins again on a new connection", async () => {
  let forgotten = false;
  const server = await standIn((sock, msg, conn) => {
    if (msg.type === "join_request") accept(sock, msg, 200 + conn);
    if (msg.type === "tracker_pose" && !forgotten) {
      forgotten = true;
      sock.send(JSON.stringify({ type: "rejection", utime: 1, client_id: "alice", seq: msg.seq, reason: "unknown_client", message: "no live client 'alice'", suppressed: 0 }));
    }
  });
  const c = new lib.NodeLiveClient({ url: server.url, clientId: "alice", skeleton: SKELETON, key: KEY, backoffInitialMs: 20 });
  const joined = [];
  c.on("joined", (j) => joined.push(j));
  await c.connect();
  c.publishPose(POSE);
  await until(() => joined.length === 2);
  assert.equal(c.session, 201);
  assert.equal(server.sockets.length, 2);
  c.close();
  await server.close();
});

// Room discovery (client/js/src/rooms.ts, docs/DEPLOY.md): the same shape
// and refusals as the C++ client's room_client_test.
test("a static room map resolves names and refuses what it cannot read", async () => {
  const map = lib.StaticRoomMap.fromText(
    '{"rooms": {"arcade-1": "wss://10.0.0.5:8765", "lab": "ws://[::1]:8765/ws"}}');
  assert.equal(map.size, 2);
  assert.equal(lib.doorUrl(await map.resolve("arcade-1")), "wss://10.0.0.5:8765/ws");
  assert.equal(lib.doorUrl(await map.resolve("lab")), "ws://[::1]:8765/ws");
  await assert.rejects(map.resolve("nowhere"), (e) => e instanceof lib.RoomError && !e.retryable);
  await assert.rejects(map.resolve("bad room"), lib.RoomError);
  for (const bad of ["[]", "{}", '{"rooms": []}', '{"rooms": {"a b": "ws://h:1"}}', '{"rooms": {"a": 5}}',
    '{"rooms": {"a": "ws://h"}}', '{"rooms": {"a": "ws://h:0"}}', '{"rooms": {"a": "ws://u@h:1"}}', "{"]) {
    assert.throws(() => lib.StaticRoomMap.fromText(bad), lib.RoomError, bad);
  }
});

test("the Agones allocator resolver asks get-or-allocate and checks the answer", async () => {
  const calls = [];
  let answer = { status: 200, body: JSON.stringify({ gameServerName: "dragon-x7k2p", address: "10.0.3.2",
    ports: [{ name: "metrics", port: 9464 }, { name: "websocket", port: 7011 }] }) };
  const fetch = async (url, init) => {
    calls.push({ url, init });
    return { status: answer.status, text: async () => answer.body };
  };
  const r = new lib.AgonesAllocatorResolver({ url: "https://alloc:443/", fleetLabels: { "sweptccd.dev/scene": "dragon" }, fetch });
  const d = await r.resolve("arcade-7");
  assert.equal(lib.doorUrl(d), "wss://10.0.3.2:7011/ws");
  assert.equal(d.source, "agones:dragon-x7k2p");
  assert.equal(calls[0].url, "https://alloc:443/gameserverallocation");
  assert.deepEqual(JSON.parse(calls[0].init.body), {
    namespace: "default",
    gameServerSelectors: [
      { matchLabels: { "sweptccd.dev/room": "arcade-7" }, gameServerState: "ALLOCATED" },
      { matchLabels: { "sweptccd.dev/scene": "dragon" }, gameServerState: "READY" }],
    metadata: { labels: { "sweptccd.dev/room": "arcade-7" } } });
  answer = { status: 429, body: "{}" };
  await assert.rejects(r.resolve("arcade-7"), (e) => e.retryable && /429/.test(e.message));
  for (const body of ["", "[]", '{"address": "10.0.3.2"}', '{"address": "a/b", "ports": [{"name": "websocket", "port": 1}]}',
    '{"address": "10.0.3.2", "ports": [{"name": "websocket", "port": 70000}]}']) {
    answer = { status: 200, body };
    await assert.rejects(r.resolve("arcade-7"), lib.RoomError, body);
  }
  await assert.rejects(r.resolve("../x"), lib.RoomError);
  assert.throws(() => new lib.AgonesAllocatorResolver({ url: "https://a", fleetLabels: {} }), lib.RoomError);
});

// Failover (docs/DEPLOY.md): the room's server goes silent (no status), the
// client takes it for dead, resolves the room again (now another server, a
// newer instance), re-joins, re-sends the unanswered poses lock-step with
// their seq, fences an event of the old instance and drops a repeated answer:
// every pair reaches the application exactly once.
test("failover: heartbeat loss, re-resolve, re-join, fence, re-send without loss or repeat", async () => {
  const status = (sock, instance) => sock.send(JSON.stringify({ type: "status", utime: 1, instance, client_id: [] }));
  const answer = (sock, msg, instance) => sock.send(JSON.stringify({ type: "contact_event", client_id: "alice", seq0: msg.seq - 1, seq1: msg.seq, pair: msg.seq - 1, result: 0, contacts: [], instance }));
  let oldAlive = true;
  const old = await standIn((sock, msg) => {
    if (msg.type === "join_request") { accept(sock, msg, 100); status(sock, 7); }
    // The old server answers pairs up to seq 2, then dies silently (no status, no answers, no FIN).
    if (msg.type === "tracker_pose" && msg.seq >= 1 && msg.seq <= 2 && oldAlive) answer(sock, msg, 7);
  });
  const fresh = await standIn(() => {});
  // The fresh server: hello of instance 9, unsigned; after the join a late
  // event of the dead run and a repeat of pair 2 (neither may be delivered).
  fresh.wss.removeAllListeners("connection");
  fresh.wss.on("connection", (sock) => {
    fresh.sockets.push(sock);
    sock.send(JSON.stringify({ type: "hello", protocol: 1, instance: 9, security: "unsigned", challenge: "b".repeat(64), server_utime: 1, room: "arcade-7", limits: { message_rate_hz: 480, max_pose_rate_hz: 240 } }));
    sock.on("message", (data) => {
      const msg = JSON.parse(String(data));
      fresh.received.push({ msg });
      if (msg.type === "join_request") {
        sock.send(JSON.stringify({ type: "join_reply", utime: 1, client_id: msg.client_id, nonce: msg.nonce, reason: 0, reason_name: "accepted", message: "", session: 200, instance: 9, silence_timeout_ms: 5000 }));
        sock.send(JSON.stringify({ type: "contact_event", client_id: "alice", seq0: 3, seq1: 4, pair: 3, result: 1, contacts: [], instance: 7 }));
        answer(sock, { seq: 2 }, 9);
      }
      if (msg.type === "tracker_pose" && msg.seq >= 3) answer(sock, msg, 9);
    });
  });
  let target = old.url;
  const resolver = { resolve: async () => lib.parseDoorUrl(target) };
  const client = new lib.NodeLiveClient({ resolver, room: "arcade-7", clientId: "alice", skeleton: SKELETON, key: KEY, backoffInitialMs: 20, heartbeatTimeoutMs: 300 });
  const seen = [];
  client.on("contact", (c) => seen.push(c.seq1));
  await client.connect();
  assert.equal(client.door, old.url + "?room=arcade-7");
  for (let k = 0; k < 5; k++) assert.equal(client.publishPose({ ...POSE, utime: 1000 + k }), true);
  await until(() => seen.length === 2);
  oldAlive = false;
  target = fresh.url;
  await until(() => client.heartbeatLosses === 1 && client.joined && client.session === 200);
  assert.equal(client.door, fresh.url + "?room=arcade-7");
  for (let k = 5; k < 8; k++) assert.equal(client.publishPose({ ...POSE, utime: 1000 + k }), true);
  await until(() => seen.length === 7);
  await new Promise((r) => setTimeout(r, 100));
  assert.deepEqual(seen, [1, 2, 3, 4, 5, 6, 7]);
  assert.equal(client.fencedEvents, 1);
  assert.equal(client.repeatedAnswers, 1);
  const resent = fresh.received.filter((r) => r.msg.type === "tracker_pose").map((r) => [r.msg.seq, r.msg.session, r.msg.utime]);
  assert.deepEqual(resent.slice(0, 3), [[2, 200, 1002], [3, 200, 1003], [4, 200, 1004]]);
  client.leave();
  await old.close();
  await fresh.close();
});

// The room a client is for (docs/WEBSOCKET.md sections 1 and 5): sent as
// ?room=, and a hello of another room refused with one clear error before
// anything is sent or delivered (the 409 of a real door: js_client_e2e).
test("a client names its room and refuses a door of another room", async () => {
  assert.equal(lib.withRoom("ws://h:1/ws", ""), "ws://h:1/ws");
  assert.equal(lib.withRoom("ws://h:1/ws", "arcade-7"), "ws://h:1/ws?room=arcade-7");
  assert.equal(lib.doorUrl(lib.parseDoorUrl("wss://[::1]:9"), "a.b"), "wss://[::1]:9/ws?room=a.b");
  assert.throws(() => lib.withRoom("ws://h:1/ws", "a&b=c"), lib.RoomError);
  assert.equal(lib.helloRoomProblem("", { room: "x" }, "d"), "");
  assert.equal(lib.helloRoomProblem("arcade-7", { room: "arcade-7" }, "d"), "");
  assert.match(lib.helloRoomProblem("arcade-7", { room: "arcade-8" }, "ws://d"), /^door 'ws:\/\/d' holds room 'arcade-8', not room 'arcade-7': refused/);
  assert.match(lib.helloRoomProblem("arcade-7", {}, "d"), /does not say which room/);
  assert.doesNotMatch(lib.helloRoomProblem("arcade-7", { room: "x\n\u001b[31m" }, "d"), /[\n\u001b]/);
  assert.throws(() => new lib.NodeLiveClient({ url: "ws://h:1/ws", room: "bad room", clientId: "a", skeleton: SKELETON }), lib.RoomError);
  const server = await standIn(accept);  // Its hello says room arcade-7.
  const errors = [];
  const client = new lib.NodeLiveClient({ url: server.url, room: "arcade-8", clientId: "alice", skeleton: SKELETON, key: KEY, reconnect: false });
  client.on("protocolError", (m) => errors.push(m));
  client.on("contact", () => assert.fail("an event of another room"));
  await assert.rejects(client.connect());
  assert.deepEqual(server.targets, ["/ws?room=arcade-8"]);
  assert.equal(client.wrongRooms, 1);
  assert.equal(server.received.length, 0);  // No join sent to another room's door.
  assert.match(errors[0], /holds room 'arcade-7', not room 'arcade-8'/);
  const right = new lib.NodeLiveClient({ url: server.url, room: "arcade-7", clientId: "bob", skeleton: SKELETON, key: KEY, reconnect: false });
  await right.connect();
  assert.equal(right.wrongRooms, 0);
  assert.equal(server.targets[1], "/ws?room=arcade-7");
  right.leave();
  await server.close();
});

test("joint frames: publishJoints converts, publishes, and refuses a bad frame with its line", async () => {
  // A two-joint set's skeleton as `sweptccd skeleton` writes names: one bone
  // "hip>knee" 0.4 m, one sphere "knee".
  const skeleton = { links: [{ name: "hip>knee", parent: null, a: [0, 0, 0], b: [0, 0.4, 0], radius: 0.08 }, { name: "knee", parent: "hip>knee", a: [0, 0, 0], b: [0, 0, 0], radius: 0.06 }] };
  const rules = lib.jointRulesOf(skeleton);
  const server = await standIn((sock, msg, conn) => {
    if (msg.type === "join_request") accept(sock, msg, 300 + conn);
  });
  const client = new lib.NodeLiveClient({ url: server.url, clientId: "legs", skeleton, key: KEY });
  await client.connect();
  const joints = new Map([
    ["hip", { position: [0, 0, 1], orientation: [1, 0, 0, 0] }],
    ["knee", { position: [0.4, 0, 1], orientation: [1, 0, 0, 0] }],
  ]);
  assert.equal(client.publishJoints(rules, joints, { utime: 5000 }), null);
  await until(() => server.received.some((r) => r.msg.type === "tracker_pose"));
  const sent = server.received.find((r) => r.msg.type === "tracker_pose").msg;
  const want = lib.jointFrameToLinks(rules, joints);
  assert.deepEqual([sent.position, sent.orientation, sent.utime, sent.seq], [want.links.map((l) => l[0]), want.links.map((l) => l[1]), 5000, 0]);
  // The bone's +Y now points along +x: the hip's frame turned by -90 degrees about z.
  assert.ok(Math.abs(sent.orientation[0][0] - Math.SQRT1_2) < 1e-12 && Math.abs(sent.orientation[0][3] + Math.SQRT1_2) < 1e-12, JSON.stringify(sent.orientation));
  const sentBefore = client.sentPoses;
  assert.match(client.publishJoints(rules, new Map([...joints, ["knee", null]]), { utime: 6000 }), /^joint knee: /);
  assert.match(client.publishJoints(rules, new Map([...joints, ["knee", { position: [0.6, 0, 1], orientation: [1, 0, 0, 0] }]]), { utime: 6000 }), /^link 0 \(hip>knee\): joints 0\.6000 m apart/);
  assert.match(client.publishJoints(rules.slice(0, 1), joints), /joint rules have 1 links, this client joined with 2/);
  assert.equal(client.sentPoses, sentBefore);
  client.leave();
  await until(() => server.received.some((r) => r.msg.type === "leave"));
  assert.equal(server.received.filter((r) => r.msg.type === "tracker_pose").length, 1);
  assert.match(client.publishJoints(rules, joints, { utime: 7000 }), /dropped/);
  await server.close();
});
