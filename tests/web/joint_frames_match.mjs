// The JavaScript joint-frame conversion (client/js/src/joint_frame.ts)
// against the C++ one (`sweptccd skeleton --joints`, JointSkeleton::Convert)
// on the same seeded frames of the WebXR joint sets (webxr-hand, webxr-body;
// every --hands option): the same frames refused (a joint null, not valid,
// a zero quaternion, a bone stretched past the tolerance) and, for every
// other frame, the same link poses (positions and orientations, up to the
// quaternion's sign, within 1e-9).
//
//   SWEPTCCD_JS_DIR=<build>/client/js node joint_frames_match.mjs SWEPTCCD WORK_DIR
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import path from "node:path";
import { pathToFileURL } from "node:url";

const [sweptccd, work] = process.argv.slice(2);
if (!sweptccd || !work) throw new Error("usage: joint_frames_match.mjs SWEPTCCD WORK_DIR");
const jsDir = process.env.SWEPTCCD_JS_DIR;
if (!jsDir) throw new Error("set SWEPTCCD_JS_DIR to <build>/client/js");
const lib = await import(pathToFileURL(path.join(jsDir, "dist", "index.js")).href);
fs.mkdirSync(work, { recursive: true });

// A seeded generator (mulberry32), so a failure replays.
function rng(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

function unitQuat(u) {
  const q = [u() - 0.5, u() - 0.5, u() - 0.5, u() - 0.5];
  const n = Math.hypot(...q);
  return q.map((v) => v / n);
}

function rotate(q, v) {
  return lib.rotate(q, v);
}

function jointNames(set) {
  const text = execFileSync(sweptccd, ["skeleton", "--from", set, "--hands", "full", "--describe"], {
    encoding: "utf8",
  });
  const names = [];
  for (const line of text.split("\n")) {
    const m = /^\s*joint\s+(\d+)\s+(\S+)/.exec(line);
    if (m) names[Number(m[1])] = m[2];
  }
  return names;
}

function check(set, hands, seed) {
  const u = rng(seed);
  const names = jointNames(set);
  assert.ok(names.length >= 25, `${set}: joint names`);
  const n = names.length;
  // The joints the links use (a bad one must refuse the frame).
  const plainPath = path.join(work, `${set}-${hands}-plain.json`);
  execFileSync(sweptccd, ["skeleton", "--from", set, "--hands", hands, "--out", plainPath]);
  const used = new Set();
  for (const r of lib.jointRulesOf(JSON.parse(fs.readFileSync(plainPath, "utf8")))) {
    for (const j of [r.a, r.b, r.from]) if (j !== undefined) used.add(names.indexOf(j));
  }
  assert.ok(!used.has(-1), `${set}: every joint a link names is in the set`);
  const usedList = [...used];
  // Calibration: joints anywhere within a metre (only the distances matter).
  const cal = names.map(() => [u() - 0.5, u() - 0.5, u() + 0.5]);
  const lines = [];
  const frames = [];
  const calLine = { utime: 1000, joints: cal.map((p) => [...p, 1, 0, 0, 0]) };
  for (let k = 0; k < 40; ++k) {
    // A rigid motion of the calibration (the bones keep their lengths, so
    // the frame is valid), 0.5 mm of noise, and random joint orientations.
    const R = unitQuat(u);
    const t = [u() * 2 - 1, u() * 2 - 1, u()];
    const joints = cal.map((p) => {
      const r = rotate(R, p);
      return [r[0] + t[0] + (u() - 0.5) * 1e-3, r[1] + t[1] + (u() - 0.5) * 1e-3, r[2] + t[2] + (u() - 0.5) * 1e-3, ...unitQuat(u)];
    });
    const valid = names.map(() => true);
    const bad = k % 8 === 5 ? ["null", "invalid", "zero", "stretch"][((k / 8) | 0) % 4] : null;
    const j = usedList[Math.floor(u() * usedList.length)];
    if (bad === "null") joints[j] = null;
    if (bad === "invalid") valid[j] = false;
    if (bad === "zero") joints[j] = [...joints[j].slice(0, 3), 0, 0, 0, 0];
    if (bad === "stretch") for (let q = 0; q < n; ++q) joints[q] = [...joints[q].slice(0, 3).map((v) => v * 1.3), ...joints[q].slice(3)];
    const line = { utime: 2000 + 8333 * k, joints, valid };
    lines.push(JSON.stringify(line));
    frames.push(line);
  }
  const tag = `${set}-${hands}`;
  const calPath = path.join(work, `${tag}-cal.jsonl`);
  const framesPath = path.join(work, `${tag}-frames.jsonl`);
  const skelPath = path.join(work, `${tag}.json`);
  const posesPath = path.join(work, `${tag}-poses.jsonl`);
  fs.writeFileSync(calPath, JSON.stringify(calLine) + "\n");
  fs.writeFileSync(framesPath, lines.join("\n") + "\n");
  execFileSync(
    sweptccd,
    ["skeleton", "--from", set, "--hands", hands, "--calibrate", calPath, "--out", skelPath, "--joints", framesPath, "--poses-out", posesPath],
    { stdio: ["ignore", "ignore", "pipe"] },
  );
  const skeleton = JSON.parse(fs.readFileSync(skelPath, "utf8"));
  const rules = lib.jointRulesOf(skeleton);
  assert.equal(rules.length, skeleton.links.length);
  const poses = fs.readFileSync(posesPath, "utf8").trim().split("\n").map((l) => JSON.parse(l));
  assert.equal(poses.length, frames.length, `${tag}: one pose line a frame`);
  let same = 0;
  let refused = 0;
  frames.forEach((f, k) => {
    const joints = new Map();
    names.forEach((name, i) => {
      const s = f.joints[i];
      joints.set(name, s === null ? null : { position: s.slice(0, 3), orientation: s.slice(3), valid: f.valid[i] });
    });
    const js = lib.jointFrameToLinks(rules, joints);
    const cpp = poses[k];
    if ("invalid" in cpp) {
      assert.ok("error" in js, `${tag} frame ${k}: C++ refused (${cpp.invalid}), JS did not`);
      ++refused;
      return;
    }
    assert.ok(!("error" in js), `${tag} frame ${k}: JS refused (${js.error}), C++ did not`);
    assert.equal(js.links.length, cpp.links.length);
    js.links.forEach(([p, q], i) => {
      const c = cpp.links[i];
      for (let d = 0; d < 3; ++d) assert.ok(Math.abs(p[d] - c[d]) <= 1e-9, `${tag} frame ${k} link ${i}: position`);
      const sign = q[0] * c[3] + q[1] * c[4] + q[2] * c[5] + q[3] * c[6] < 0 ? -1 : 1;
      for (let d = 0; d < 4; ++d) {
        assert.ok(Math.abs(sign * q[d] - c[3 + d]) <= 1e-9, `${tag} frame ${k} link ${i}: orientation ${q} vs ${c.slice(3)}`);
      }
    });
    ++same;
  });
  // Frames 5, 13, 21, 29, 37 (a used joint null, not valid, with a zero
  // quaternion, every bone stretched 30 %, null) are refused by both; a
  // skeleton of fixed-length bones only (webxr-hand --hands simple) keeps
  // the stretched one.
  const expectRefused = set === "webxr-hand" && hands === "simple" ? 4 : 5;
  assert.equal(refused, expectRefused, `${tag}: frames refused`);
  assert.equal(same, 40 - expectRefused, `${tag}: frames compared`);
  console.log(`${tag}: ${same} frames equal, ${refused} refused by both`);
}

let seed = 31400;
for (const hands of ["full", "simple"]) check("webxr-hand", hands, seed++);
for (const hands of ["full", "simple", "none"]) check("webxr-body", hands, seed++);
console.log("joint frames: JavaScript and C++ agree");
