// The JavaScript client under Node against the real daemon's WebSocket door
// (run by js_client_e2e.sh inside a private network namespace):
//   - a viewer subscribes and sees the room, the joined client's skeleton,
//     its forwarded poses, its contact events and status;
//   - a wrong key is refused (bad_proof) and not retried;
//   - a client of another room is refused by the door (409 to ?room=)
//     before any frame; the room's own clients name it (js_client_e2e.sh:
//     --room js-room) and pass the hello's room check;
//   - the client streams the bundled walk lock-step (each pose after the
//     previous pair's answer) and every contact_event equals `sweptccd
//     query` on the same samples (result, s_lo, s_hi, initially_colliding,
//     the first witness's link and object);
//   - a pose out of order gets a rejection (non_increasing_seq);
//   - the connection drops: the client reconnects, joins again with a
//     greater session, and its new stream is answered exactly again;
//   - leave: the viewer's room no longer holds the client.
//   - a client of the daemon's configuration (jswalker, its own key) joins
//     through the door; the walk is answered equal to `sweptccd query`.
//   node js_client_e2e.mjs URL KEY_FILE SKELETON POSES EXPECTED WALKER_KEY_FILE
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import path from "node:path";
import { pathToFileURL } from "node:url";

const lib = await import(pathToFileURL(path.join(process.env.SWEPTCCD_JS_DIR, "dist", "node.js")).href);
const [url, keyFile, skeletonFile, posesFile, expectedFile, walkerKeyFile] = process.argv.slice(2);
const key = readFileSync(keyFile, "utf8");
const skeleton = JSON.parse(readFileSync(skeletonFile, "utf8"));
const poses = lib.parsePoseLines(readFileSync(posesFile, "utf8"));
const expected = readFileSync(expectedFile, "utf8").split("\n").filter((l) => l.trim()).map((l) => JSON.parse(l));
const RESULTS = { free: 0, contact: 1, invalid: 2 };
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
async function until(what, ms, why) {
  for (const t0 = Date.now(); !what(); await sleep(5)) {
    if (Date.now() - t0 > ms) throw new Error(`js_client_e2e: timed out after ${ms} ms waiting for ${why}`);
  }
}
const log = (...a) => console.log("js_client_e2e:", ...a);

// The viewer first: it must see everything below.
const viewer = new lib.NodeViewer({ url, key });
const seen = { rooms: [], poses: 0, contacts: 0, status: null };
viewer.on("room", (r) => seen.rooms.push(r));
viewer.on("pose", (p) => { if (p.client_id === "jsalice") seen.poses++; });
viewer.on("contact", (e) => { if (e.client_id === "jsalice") seen.contacts++; });
viewer.on("status", (s) => { seen.status = s; });
await viewer.connect();
log(`viewer subscribed (${viewer.serverHello.security}, instance ${viewer.serverHello.instance})`);
// hello tells the daemon's status period (js_client_e2e.sh: --status-period 0.2).
assert.equal(viewer.serverHello.limits.status_period_ms, 200);

// A wrong key: bad_proof, and the client gives up at once.
const wrong = new lib.NodeLiveClient({ url, key: "11".repeat(32), clientId: "jsmallory", skeleton, backoffInitialMs: 50 });
await assert.rejects(wrong.connect(), (e) => e.code === "bad_proof");
assert.equal(wrong.connects, 1);
log("a wrong key is refused: bad_proof");

// Another room's client: the door refuses the upgrade with 409, one clear error.
const lost = new lib.NodeLiveClient({ url, key, clientId: "jslost", skeleton, room: "other-room", reconnect: false });
const lostErrors = [];
lost.on("protocolError", (m) => lostErrors.push(m));
lost.on("contact", () => assert.fail("an event delivered to another room's client"));
await assert.rejects(lost.connect());
assert.equal(lost.wrongRooms, 1);
assert.equal(lost.serverHello, null);
assert.match(lostErrors.join("\n"), /refused room 'other-room' \(409\)/);
log("a client of another room is refused: 409");

const alice = new lib.NodeLiveClient({ url, key, clientId: "jsalice", skeleton, room: "js-room", backoffInitialMs: 50 });
const events = [];
const rejections = [];
const joins = [];
let status = null;
alice.on("contact", (e) => events.push(e));
alice.on("rejection", (r) => rejections.push(r));
alice.on("joined", (j) => joins.push(j));
alice.on("status", (s) => { status = s; });
await alice.connect();
const session0 = alice.session;
log(`joined: session ${session0}`);
await until(() => seen.rooms.some((r) => r.clients.some((c) => c.client_id === "jsalice")), 5000, "the room with jsalice");
const inRoom = seen.rooms.at(-1).clients.find((c) => c.client_id === "jsalice");
assert.deepEqual(inRoom.link_name, alice.skeleton.link_name);
assert.deepEqual(inRoom.parent, alice.skeleton.parent);
assert.deepEqual(inRoom.radius, alice.skeleton.radius);
assert.equal(inRoom.door, "websocket");

// Lock-step: pose k after pair k-2's answer, every answer equal to the query's.
function check(e, want, k, what) {
  assert.equal(e.seq0, k - 1, `${what}: seq0`);
  assert.equal(e.seq1, k, `${what}: seq1`);
  assert.equal(e.result, RESULTS[want.result], `${what}: result ${e.result_name}, query ${want.result}`);
  if (want.result !== "contact") return 0;
  assert.equal(e.s_lo, want.s_lo, `${what}: s_lo`);
  assert.equal(e.s_hi, want.s_hi, `${what}: s_hi`);
  assert.equal(e.initially_colliding, want.initially_colliding, `${what}: initially_colliding`);
  assert.ok(e.contacts.length > 0, `${what}: a contact without a witness`);
  assert.equal(e.contacts[0].link, want.contacts[0].link, `${what}: witness link`);
  assert.equal(e.contacts[0].object, want.contacts[0].object, `${what}: witness object`);
  return 1;
}
async function lockstep(count, what) {
  const first = events.length;
  let contacts = 0;
  for (let k = 0; k < count; k++) {
    const p = poses[k];
    assert.ok(alice.publishPose({ utime: p.utime, seq: k, position: p.position, orientation: p.orientation }), `${what}: pose ${k} not sent`);
    if (k === 0) continue;
    await until(() => events.length >= first + k, 10000, `${what}: the event of pair ${k - 1}`);
    contacts += check(events[first + k - 1], expected[k - 1], k, `${what} pair ${k - 1}`);
  }
  await sleep(100);
  assert.equal(events.length, first + count - 1, `${what}: events beyond the poses`);
  return contacts;
}
const contacts = await lockstep(poses.length, "walk");
const wantContacts = expected.filter((e) => e.result === "contact").length;
assert.equal(contacts, wantContacts);
assert.ok(contacts > 0, "the walk has no contact: the comparison proves little");
log(`walk: ${events.length} events equal to sweptccd query, ${contacts} contacts`);

// A pose out of order: rejected with its seq.
const last = poses.at(-1);
alice.publishPose({ utime: last.utime + 1000, seq: poses.length - 1, position: last.position, orientation: last.orientation });
await until(() => rejections.length > 0, 5000, "the rejection");
assert.equal(rejections[0].reason, "non_increasing_seq");
assert.equal(rejections[0].seq, poses.length - 1);
assert.equal(rejections[0].client_id, "jsalice");
log(`rejection: ${rejections[0].reason}`);

// The viewer saw poses, contacts and status of jsalice; the client its status.
// (status is periodic: wait for one that counts every pair answered.)
const answered = (s) => {
  const i = s ? s.client_id.indexOf("jsalice") : -1;
  return i >= 0 && s.rejected[i] >= 1 ? s.pairs_answered[i] : -1;
};
await until(() => answered(seen.status) >= poses.length - 1 && answered(status) >= poses.length - 1, 5000, "status with every pair and the rejection of jsalice");
assert.ok(seen.poses > 0, "the viewer got no forwarded pose");
assert.ok(seen.contacts > 0, "the viewer got no contact event");
const k = seen.status.client_id.indexOf("jsalice");
assert.equal(seen.status.rejected[k], 1, "status: the one rejection");
log(`viewer: ${seen.poses} forwarded poses (latest-wins), ${seen.contacts} contact events, status pairs_answered ${seen.status.pairs_answered[k]}`);

// The connection drops: reconnect, join again (same nonce), a greater session.
alice.socket.terminate();
await until(() => joins.length === 2, 10000, "the re-join");
assert.equal(joins[1].rejoin, true);
assert.ok(alice.session > session0, `session ${alice.session} not greater than ${session0}`);
const again = await lockstep(12, "after re-join");
log(`re-joined: session ${alice.session}, 11 more events equal to sweptccd query (${again} contacts)`);

// Leave: the room forgets jsalice.
const rooms = seen.rooms.length;
alice.leave();
await until(() => seen.rooms.length > rooms && !seen.rooms.at(-1).clients.some((c) => c.client_id === "jsalice"), 5000, "the room without jsalice");

// A configured client (docs/WEBSOCKET.md "Configured clients"): its own key
// proves the join; answered as over LCM; the viewer sees it as "config".
const walkerEvents = [];
const walker = new lib.NodeLiveClient({ url, key: readFileSync(walkerKeyFile, "utf8"), clientId: "jswalker", skeleton, room: "js-room" });
walker.on("contact", (e) => walkerEvents.push(e));
await walker.connect();
let walkerContacts = 0;
for (let k = 0; k < poses.length; k++) {
  const p = poses[k];
  assert.ok(walker.publishPose({ utime: p.utime, seq: k, position: p.position, orientation: p.orientation }));
  if (k === 0) continue;
  await until(() => walkerEvents.length >= k, 10000, `jswalker: the event of pair ${k - 1}`);
  walkerContacts += check(walkerEvents[k - 1], expected[k - 1], k, `jswalker pair ${k - 1}`);
}
assert.equal(walkerContacts, wantContacts);
assert.equal(seen.rooms.at(-1).clients.find((c) => c.client_id === "jswalker").door, "config");
walker.leave();
log(`configured client jswalker: ${walkerEvents.length} events equal to sweptccd query`);
viewer.close();
log("left; passed");
