#!/usr/bin/env node
// The Node example of the JavaScript client (README, docs/WEBSOCKET.md):
// joins a room through the daemon's WebSocket door with a skeleton (SPEC
// section 1), streams a pose file (SPEC section 2) at its own pace (the
// utime steps, or --rate), prints every contact event, shared-world contact
// and rejection as one line, then leaves.
//
//   node <build>/client/js/examples/node_example.mjs --url ws://127.0.0.1:7700/ws \
//     --key room.key --id alice --skeleton skeleton.json --poses poses.jsonl [--rate 90] [--count N]
//
// Without --key the room must be unsigned (lab bench). For wss:// with a
// self-signed certificate give --ca cert.pem.
import { readFileSync } from "node:fs";
import { parseArgs } from "node:util";
import { NodeLiveClient, parsePoseLines, RESULT } from "@sweptccd/client/node";

const { values: opt } = parseArgs({
  options: {
    url: { type: "string", default: "ws://127.0.0.1:7700/ws" },
    key: { type: "string" },
    id: { type: "string", default: "alice" },
    skeleton: { type: "string" },
    poses: { type: "string" },
    rate: { type: "string" },
    count: { type: "string" },
    ca: { type: "string" },
  },
});
if (!opt.skeleton || !opt.poses) {
  console.error("node_example: --skeleton FILE and --poses FILE are needed");
  process.exit(2);
}
const skeleton = JSON.parse(readFileSync(opt.skeleton, "utf8"));
let poses = parsePoseLines(readFileSync(opt.poses, "utf8"));
if (opt.count) poses = poses.slice(0, Number(opt.count));
const client = new NodeLiveClient({
  url: opt.url,
  key: opt.key ? readFileSync(opt.key, "utf8") : undefined,
  ca: opt.ca ? readFileSync(opt.ca) : undefined,
  clientId: opt.id,
  skeleton,
});
const names = client.skeleton.link_name;
let events = 0;
let contacts = 0;
let lastSeq = -1; // seq1 of the latest answer (the daemon may skip pairs when behind: latest-wins)
client.on("joined", ({ reply, rejoin }) => console.log(`${rejoin ? "re-joined" : "joined"} as ${reply.client_id}: session ${reply.session}`));
client.on("contact", (e) => {
  events++;
  lastSeq = e.seq1;
  if (e.result !== RESULT.CONTACT) return;
  contacts++;
  const w = e.contacts[0];
  console.log(`pair ${e.pair} (seq ${e.seq0}-${e.seq1}): contact at s [${e.s_lo}, ${e.s_hi}]` +
    (w ? `, link ${names[w.link] ?? w.link} against environment object ${w.object} at [${w.point_env.map((x) => x.toFixed(3))}]` : ""));
});
client.on("sharedContact", (s) => {
  for (const e of s.entries) if (e.result === RESULT.CONTACT) console.log(`pair ${s.pair}: contact with ${e.entity} at s [${e.s_lo}, ${e.s_hi}]`);
});
client.on("rejection", (r) => console.log(`rejected seq ${r.seq}: ${r.reason}: ${r.message}`));
client.on("close", (c) => console.log(`connection closed (${c.code}); ${c.reconnectInMs >= 0 ? `reconnecting in ${c.reconnectInMs} ms` : "not reconnecting"}`));

try {
  await client.connect();
} catch (e) {
  console.error(`node_example: ${e.message}`);
  process.exit(1);
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const start = Date.now();
for (let k = 0; k < poses.length; k++) {
  const p = poses[k];
  const due = opt.rate ? (k * 1000) / Number(opt.rate) : (p.utime - poses[0].utime) / 1000;
  await sleep(Math.max(0, start + due - Date.now()));
  client.publishPose({ utime: p.utime, position: p.position, orientation: p.orientation });
}
// The last pose's answer, then leave.
for (let waited = 0; lastSeq < poses.length - 1 && waited < 3000; waited += 20) await sleep(20);
client.leave();
console.log(`left: ${poses.length} poses sent, ${events} events answering up to seq ${lastSeq}, ${contacts} contacts`);
