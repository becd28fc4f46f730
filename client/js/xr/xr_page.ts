/// <reference types="webxr" />
// The WebXR pose source page (issue 29): joins as a live client and streams
// what the headset tracks (src/xr_skeleton.ts); the headset-free mode
// replays a skeleton + pose file through the same Streamer (join, publish,
// counters). Test hook: window.__sweptccdXr.

import {
  LiveClient,
  PoseSample,
  RESULT,
  RigidPose,
  SkeletonFile,
  Vec3,
  XrSkeleton,
  XrSnapshot,
  HAND_JOINTS,
  buildXrSkeleton,
  escapeForDisplay,
  parsePoseLines,
  xrSample,
  xrToRoom,
} from "../src/index.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const statsEl = $<HTMLDivElement>("stats");
const params = new URLSearchParams(location.hash.slice(1));
$<HTMLInputElement>("clientId").value = params.get("id") ?? `xr-${Math.floor(Math.random() * 1e6)}`;
if (params.get("key")) {
  $<HTMLInputElement>("key").value = params.get("key")!;
  history.replaceState(null, "", location.pathname + location.search);
}

interface Stats { state: string; joined: boolean; session: number; links: number; sent: number; dropped: number; events: number; contacts: number; shared_contacts: number; rejections: number; last: string; }
/** The answers of this page's pairs (the test hook compares them with sweptccd query). */
const answers: { seq0: number; seq1: number; result: number; s_lo: number; s_hi: number }[] = [];
const stats: Stats = { state: "idle", joined: false, session: 0, links: 0, sent: 0, dropped: 0, events: 0, contacts: 0, shared_contacts: 0, rejections: 0, last: "" };
function show(): void {
  statsEl.textContent = Object.entries(stats).map(([k, v]) => `${k.padEnd(16)} ${v}`).join("\n");
}

/** One live client fed by either source: the same join, the same publishing. */
class Streamer {
  client: LiveClient | null = null;
  async start(skeleton: SkeletonFile, motion: number): Promise<void> {
    this.client?.leave();
    const key = $<HTMLInputElement>("key").value.trim();
    const url = `${location.protocol === "https:" ? "wss:" : "ws:"}//${location.host}/ws`;
    const c = new LiveClient({ url, key: key || undefined, clientId: $<HTMLInputElement>("clientId").value.trim(), skeleton, motion });
    this.client = c;
    stats.links = c.skeleton.link_name.length;
    c.on("state", (s) => { stats.state = s; show(); });
    c.on("joined", ({ reply }) => { stats.joined = true; stats.session = reply.session; show(); });
    c.on("close", () => { stats.joined = false; show(); });
    c.on("contact", (e) => {
      stats.events++;
      if (answers.length < 10000) answers.push({ seq0: e.seq0, seq1: e.seq1, result: e.result, s_lo: e.s_lo, s_hi: e.s_hi });
      if (e.result === RESULT.CONTACT) {
        stats.contacts++;
        const w = e.contacts[0];
        stats.last = `pair ${e.pair}: ${escapeForDisplay(c.skeleton.link_name[w?.link] ?? "?", 64)} touches environment object ${w?.object}`;
      }
      show();
    });
    c.on("sharedContact", (s) => {
      for (const e of s.entries) if (e.result === RESULT.CONTACT) { stats.shared_contacts++; stats.last = `pair ${s.pair}: touches ${escapeForDisplay(e.entity, 64)}`; }
      show();
    });
    c.on("rejection", (r) => { stats.rejections++; stats.last = `rejected: ${escapeForDisplay(r.reason, 40)}: ${escapeForDisplay(r.message, 120)}`; show(); });
    await c.connect();
  }
  push(links: RigidPose[], utime?: number, seq?: number): void {
    const c = this.client;
    if (!c) return;
    const ok = c.publishPose({ position: links.map((l) => l.position), orientation: links.map((l) => l.orientation), utime, seq });
    if (ok) stats.sent++;
    else stats.dropped++;
  }
}
const streamer = new Streamer();

// ---- the headset ----
function roomPlacement(): { origin: Vec3; yaw: number } {
  const o = $<HTMLInputElement>("origin").value.trim().split(/[\s,]+/).map(Number);
  const yaw = (Number($<HTMLInputElement>("yaw").value) * Math.PI) / 180;
  return { origin: o.length === 3 && o.every(Number.isFinite) ? (o as Vec3) : [0, 0, 0], yaw: Number.isFinite(yaw) ? yaw : 0 };
}

function rigid(p: XRPose | undefined | null, place: { origin: Vec3; yaw: number }): RigidPose | undefined {
  if (!p) return undefined;
  const t = p.transform;
  return xrToRoom({ position: [t.position.x, t.position.y, t.position.z], orientation: [t.orientation.w, t.orientation.x, t.orientation.y, t.orientation.z] }, place.origin, place.yaw);
}

function snapshot(frame: XRFrame, space: XRReferenceSpace, place: { origin: Vec3; yaw: number }): XrSnapshot {
  const s: XrSnapshot = { head: rigid(frame.getViewerPose(space), place) ?? null, controllers: {}, hands: {} };
  for (const src of frame.session.inputSources) {
    const side = src.handedness === "left" || src.handedness === "right" ? src.handedness : null;
    if (!side) continue;
    if (src.hand) {
      const joints = new Map<string, { position: Vec3; orientation: [number, number, number, number]; radius: number }>();
      for (const name of HAND_JOINTS) {
        const jointSpace = src.hand.get(name as XRHandJoint);
        const jp = jointSpace && frame.getJointPose ? frame.getJointPose(jointSpace, space) : null;
        const r = rigid(jp, place);
        if (jp && r) joints.set(name, { ...r, radius: jp.radius ?? 0.01 });
      }
      s.hands[side] = joints;
    } else if (src.gripSpace) {
      const r = rigid(frame.getPose(src.gripSpace, space), place);
      if (r) s.controllers[side] = r;
    }
  }
  const body = (frame as unknown as { body?: Map<string, XRSpace> }).body;
  if (body && typeof body.forEach === "function") {
    const m = new Map<string, RigidPose>();
    body.forEach((jointSpace, name) => {
      const r = rigid(frame.getPose(jointSpace, space), place);
      if (r) m.set(name, r);
    });
    s.body = m;
  }
  return s;
}

let spaceRef: XRReferenceSpace | null = null;
async function enterVr(): Promise<void> {
  const xr = navigator.xr!;
  const session = await xr.requestSession("immersive-vr", { requiredFeatures: ["local-floor"], optionalFeatures: ["hand-tracking", "body-tracking"] });
  const canvas = document.createElement("canvas");
  const gl = canvas.getContext("webgl2", { xrCompatible: true }) as WebGL2RenderingContext;
  session.updateRenderState({ baseLayer: new XRWebGLLayer(session, gl) });
  spaceRef = await session.requestReferenceSpace("local-floor");
  const place = roomPlacement();
  let skeleton: XrSkeleton | null = null;
  let last: RigidPose[] | null = null;
  const t0 = performance.now();
  const onFrame = (_t: number, frame: XRFrame) => {
    session.requestAnimationFrame(onFrame);
    const layer = session.renderState.baseLayer!;
    gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer);
    gl.clearColor(0.12, 0.14, 0.16, 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    const snap = snapshot(frame, spaceRef!, place);
    if (!skeleton) {
      // Calibrate on the first frame where every offered hand has all 25 joints (or after 2 s).
      const handsComplete = (["left", "right"] as const).every((h) => !snap.hands[h] || snap.hands[h]!.size === 25);
      if (!snap.head || (!handsComplete && performance.now() - t0 < 2000)) return;
      skeleton = buildXrSkeleton(snap);
      streamer.start(skeleton.skeleton, 1).catch((e) => { stats.last = escapeForDisplay(String(e.message), 160); show(); });
    }
    const sample = xrSample(skeleton, snap, last);
    if (!sample) return;
    last = sample;
    if (streamer.client?.joined) streamer.push(sample);
  };
  session.requestAnimationFrame(onFrame);
  session.addEventListener("end", () => streamer.client?.leave());
}

if (navigator.xr) {
  navigator.xr.isSessionSupported("immersive-vr").then((ok) => {
    $<HTMLButtonElement>("enterVr").disabled = !ok;
  }).catch(() => {});
}
$<HTMLButtonElement>("enterVr").onclick = () => enterVr().catch((e) => { stats.last = escapeForDisplay(String(e.message), 160); show(); });

// ---- headset-free replay: the same Streamer ----
async function replay(skeletonText: string, posesText: string, speed = 1): Promise<number> {
  const skeleton = JSON.parse(skeletonText) as SkeletonFile;
  const poses: PoseSample[] = parsePoseLines(posesText);
  await streamer.start(skeleton, 0);
  const start = performance.now();
  for (let k = 0; k < poses.length; k++) {
    const due = (poses[k].utime - poses[0].utime) / 1000 / speed;
    const wait = start + due - performance.now();
    if (wait > 0) await new Promise((r) => setTimeout(r, wait));
    const p = poses[k];
    streamer.push(p.position.map((position, i) => ({ position, orientation: p.orientation[i] })), p.utime, k);
    show();
  }
  return poses.length;
}
$<HTMLButtonElement>("replay").onclick = async () => {
  const sk = $<HTMLInputElement>("skeletonFile").files?.[0];
  const ps = $<HTMLInputElement>("posesFile").files?.[0];
  if (!sk || !ps) { stats.last = "choose a skeleton and a pose file"; show(); return; }
  try {
    await replay(await sk.text(), await ps.text(), Number($<HTMLInputElement>("speed").value) || 1);
  } catch (e) {
    stats.last = escapeForDisplay(String((e as Error).message), 160);
    show();
  }
};

(window as unknown as { __sweptccdXr: unknown }).__sweptccdXr = {
  replay,
  stats: () => ({ ...stats }),
  answers: () => answers.slice(),
  leave: () => streamer.client?.leave(),
};
show();
