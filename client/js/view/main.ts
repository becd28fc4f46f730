// The live view (issue 29): served by the daemon's WebSocket door at "/".
// Subscribes as a viewer and draws the room's static scene (/scene.json,
// /scene/N.bin), every avatar's capsules moving live (skeletons from `room`,
// forwarded poses), tracked objects, each contact flashing at its witness
// point with the link names, a strip of recent contacts and each client's
// latency and rejection counts (status).
//
// Smooth with many avatars: all capsules of all avatars are two instanced
// meshes (cylinders, end spheres); a pose only stores itself as its client's
// latest, and each animation frame applies at most one pose per client.
//
// The room key (signed rooms) comes from the page's fragment (#key=<hex>,
// never sent to the server) or the form; it stays in this tab
// (sessionStorage). Test hook: window.__sweptccdView (see ViewHook).

import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import {
  ContactEvent,
  Hello,
  ObjectPose,
  Room,
  RoomClient,
  SceneDescription,
  SharedContact,
  Status,
  TrackerPose,
  Vec3,
  escapeForDisplay,
  parseKey,
  parseSceneMesh,
  transformPoint,
} from "../src/index.js";

const BACKGROUND = 0x20242a;
const MARKER_COLOR = "#ff00ff";
const MARKER_LIFE_MS = 1500;
const STRIP_LENGTH = 12;
const PALETTE = [0x4fc3f7, 0xffb74d, 0x81c784, 0xe57373, 0xba68c8, 0xfff176, 0x4db6ac, 0xf06292,
                 0x9575cd, 0xaed581, 0xff8a65, 0x90a4ae, 0x64b5f6, 0xdce775, 0x4dd0e1, 0xa1887f];

const canvas = document.getElementById("canvas") as HTMLCanvasElement;
const statusEl = document.getElementById("status")!;
const clientsBody = document.querySelector("#clients tbody")!;
const stripEl = document.getElementById("strip")!;
const labelsEl = document.getElementById("labels")!;

const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
renderer.setClearColor(BACKGROUND);
const scene = new THREE.Scene();
THREE.Object3D.DEFAULT_UP.set(0, 0, 1); // SweptCCD's worlds are z-up (import-bvh --up z).
const camera = new THREE.PerspectiveCamera(50, 1, 0.05, 500);
camera.up.set(0, 0, 1);
camera.position.set(-6, -8, 6);
const controls = new OrbitControls(camera, canvas);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404040, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.2);
sun.position.set(3, -4, 8);
scene.add(sun);

const envGroup = new THREE.Group();
scene.add(envGroup);
const objectGroup = new THREE.Group();
scene.add(objectGroup);

// ---- avatars: two instanced meshes for every capsule of every avatar ----
interface Avatar {
  client: RoomClient;
  first: number; // its first instance slot
  links: number;
  color: THREE.Color;
  latest: TrackerPose | null;
  /** The pose the instanced meshes show now. */
  drawn: TrackerPose | null;
  dirty: boolean;
  door: string;
}
const avatars = new Map<string, Avatar>();
let capacity = 0;
let cylinders: THREE.InstancedMesh | null = null;
let spheres: THREE.InstancedMesh | null = null;
const cylGeo = new THREE.CylinderGeometry(1, 1, 1, 10, 1, true);
cylGeo.rotateX(Math.PI / 2); // axis along z: the instance's z is the segment
const sphGeo = new THREE.SphereGeometry(1, 8, 5);
const avatarMat = new THREE.MeshLambertMaterial({ color: 0xffffff });
const zero = new THREE.Matrix4().makeScale(0, 0, 0);

function ensureCapacity(links: number): void {
  if (links <= capacity && cylinders) return;
  capacity = Math.max(64, 1 << Math.ceil(Math.log2(Math.max(links, 1))));
  for (const m of [cylinders, spheres]) if (m) { scene.remove(m); m.dispose(); }
  cylinders = new THREE.InstancedMesh(cylGeo, avatarMat, capacity);
  spheres = new THREE.InstancedMesh(sphGeo, avatarMat, 2 * capacity);
  for (const m of [cylinders, spheres]) {
    m.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    m.frustumCulled = false;
    m.count = 0;
    scene.add(m);
  }
}

const isNum = (x: unknown) => typeof x === "number" && Number.isFinite(x);
const isVec = (v: unknown, n: number) => Array.isArray(v) && v.length === n && v.every(isNum);

function wellFormedSkeleton(c: RoomClient): boolean {
  if (!c || typeof c.client_id !== "string" || !Array.isArray(c.link_name)) return false;
  const n = c.link_name.length;
  return n >= 1 && n <= 256 && [c.parent, c.a, c.b, c.radius].every((x) => Array.isArray(x) && x.length === n) &&
    c.a!.every((v) => isVec(v, 3)) && c.b!.every((v) => isVec(v, 3)) && c.radius!.every((r) => isNum(r) && r > 0);
}

function setRoom(room: Room): void {
  const old = avatars;
  const next = new Map<string, Avatar>();
  let slot = 0;
  // Hostile input: only well-formed skeletons are drawn (equal lengths, 1-256
  // links, finite numbers, radius > 0).
  const usable = (Array.isArray(room.clients) ? room.clients : []).filter(wellFormedSkeleton);
  const total = usable.reduce((n, c) => n + c.link_name!.length, 0);
  ensureCapacity(total);
  usable.forEach((c, i) => {
    const prev = old.get(c.client_id);
    next.set(c.client_id, {
      client: c,
      first: slot,
      links: c.link_name!.length,
      color: new THREE.Color(PALETTE[i % PALETTE.length]),
      latest: prev?.latest ?? null,
      drawn: null,
      dirty: true,
      door: typeof c.door === "string" ? c.door : "",
    });
    slot += c.link_name!.length;
  });
  avatars.clear();
  for (const [k, v] of next) avatars.set(k, v);
  cylinders!.count = slot;
  spheres!.count = 2 * slot;
  for (const a of avatars.values()) {
    for (let i = 0; i < a.links; i++) {
      cylinders!.setMatrixAt(a.first + i, zero);
      spheres!.setMatrixAt(2 * (a.first + i), zero);
      spheres!.setMatrixAt(2 * (a.first + i) + 1, zero);
      cylinders!.setColorAt(a.first + i, a.color);
      spheres!.setColorAt(2 * (a.first + i), a.color);
      spheres!.setColorAt(2 * (a.first + i) + 1, a.color);
    }
  }
  for (const m of [cylinders!, spheres!]) {
    m.instanceMatrix.needsUpdate = true;
    if (m.instanceColor) m.instanceColor.needsUpdate = true;
  }
  objectsFromRoom(room);
  renderClientTable();
}

const tmpA = new THREE.Vector3();
const tmpB = new THREE.Vector3();
const tmpMid = new THREE.Vector3();
const tmpDir = new THREE.Vector3();
const tmpQ = new THREE.Quaternion();
const tmpS = new THREE.Vector3();
const tmpM = new THREE.Matrix4();
const zAxis = new THREE.Vector3(0, 0, 1);

/** World ends of link i of avatar a in its latest pose (or the one drawn). */
function linkEnds(a: Avatar, i: number, drawn = false): [Vec3, Vec3] | null {
  const p = drawn ? a.drawn : a.latest;
  if (!p || p.position.length !== a.links) return null;
  const c = a.client;
  return [transformPoint(p.position[i], p.orientation[i], c.a![i]), transformPoint(p.position[i], p.orientation[i], c.b![i])];
}

let posesApplied = 0;
let frozen = false;
function applyPoses(): void {
  let changed = false;
  for (const a of avatars.values()) {
    // Frozen: avatars keep the pose drawn; one not drawn yet (new, or
    // re-slotted by a room update) still gets its latest.
    if (!a.dirty || (frozen && a.drawn)) continue;
    a.dirty = false;
    a.drawn = a.latest;
    changed = true;
    posesApplied++;
    for (let i = 0; i < a.links; i++) {
      const ends = linkEnds(a, i);
      if (!ends) continue;
      const r = a.client.radius![i];
      tmpA.fromArray(ends[0]);
      tmpB.fromArray(ends[1]);
      tmpDir.subVectors(tmpB, tmpA);
      const len = tmpDir.length();
      tmpMid.addVectors(tmpA, tmpB).multiplyScalar(0.5);
      if (len > 1e-9) tmpQ.setFromUnitVectors(zAxis, tmpDir.multiplyScalar(1 / len));
      else tmpQ.identity();
      tmpS.set(r, r, Math.max(len, 1e-6));
      cylinders!.setMatrixAt(a.first + i, tmpM.compose(tmpMid, tmpQ, tmpS));
      tmpS.set(r, r, r);
      tmpQ.identity();
      spheres!.setMatrixAt(2 * (a.first + i), tmpM.compose(tmpA, tmpQ, tmpS));
      spheres!.setMatrixAt(2 * (a.first + i) + 1, tmpM.compose(tmpB, tmpQ, tmpS));
    }
  }
  if (changed) {
    cylinders!.instanceMatrix.needsUpdate = true;
    spheres!.instanceMatrix.needsUpdate = true;
  }
}

// ---- the static scene and tracked objects ----
interface SceneInfo { desc: SceneDescription | null; envNames: string[]; }
const sceneInfo: SceneInfo = { desc: null, envNames: [] };
const objectMeshes = new Map<number, THREE.Mesh>(); // scene index -> mesh
const objectIds = new Map<string, number>(); // object_id -> scene index
const envBox = new THREE.Box3();

async function loadScene(): Promise<void> {
  const res = await fetch("/scene.json", { cache: "no-cache" });
  if (!res.ok) throw new Error(`/scene.json: HTTP ${res.status}`);
  const desc = (await res.json()) as SceneDescription;
  if (!desc || !Array.isArray(desc.meshes)) throw new Error("/scene.json: no meshes");
  sceneInfo.desc = desc;
  const envMat = new THREE.MeshLambertMaterial({ color: 0xb8b8b0, transparent: true, opacity: 0.35, depthWrite: false, side: THREE.DoubleSide });
  const objMat = new THREE.MeshLambertMaterial({ color: 0xffe082 });
  for (const m of desc.meshes) {
    if (typeof m.index !== "number" || !/^\/scene\/\d+\.bin$/.test(String(m.url))) continue;
    const r = await fetch(m.url, { cache: "no-cache" });
    if (!r.ok) throw new Error(`${m.url}: HTTP ${r.status}`);
    const data = parseSceneMesh(await r.arrayBuffer());
    const geo = new THREE.BufferGeometry();
    geo.setAttribute("position", new THREE.BufferAttribute(data.positions, 3));
    geo.setIndex(new THREE.BufferAttribute(data.indices, 1));
    geo.computeVertexNormals();
    geo.computeBoundingBox();
    if (m.kind === "object") {
      const mesh = new THREE.Mesh(geo, objMat);
      mesh.visible = false; // until its first pose
      objectMeshes.set(m.index, mesh);
      if (m.object_id) objectIds.set(m.object_id, m.index);
      objectGroup.add(mesh);
    } else {
      const mesh = new THREE.Mesh(geo, envMat);
      mesh.renderOrder = 2;
      envGroup.add(mesh);
      envBox.union(geo.boundingBox!);
    }
  }
  fitCamera();
}

function fitCamera(): void {
  const box = envBox.isEmpty() ? new THREE.Box3(new THREE.Vector3(-3, -3, 0), new THREE.Vector3(3, 3, 2)) : envBox;
  const center = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3());
  const radius = Math.max(size.length() / 2, 1);
  controls.target.copy(center);
  camera.position.set(center.x - 0.45 * radius, center.y - 1.1 * radius, center.z + 1.2 * radius);
  camera.near = radius / 200;
  camera.far = radius * 20;
  camera.updateProjectionMatrix();
  controls.update();
}

/** Points the camera at every avatar's capsules (key "f"; "r": the whole room again). */
function fitToAvatars(): boolean {
  const box = new THREE.Box3();
  for (const a of avatars.values()) {
    for (let i = 0; i < a.links; i++) {
      const e = linkEnds(a, i, true);
      if (!e) continue;
      const r = a.client.radius![i];
      for (const p of e) {
        box.expandByPoint(new THREE.Vector3(p[0] - r, p[1] - r, p[2] - r));
        box.expandByPoint(new THREE.Vector3(p[0] + r, p[1] + r, p[2] + r));
      }
    }
  }
  if (box.isEmpty()) return false;
  const center = box.getCenter(new THREE.Vector3());
  const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 0.5);
  const dist = (1.15 * radius) / Math.sin((camera.fov * Math.PI) / 360);
  const dir = new THREE.Vector3(-0.35, -1, 0.6).normalize();
  controls.target.copy(center);
  camera.position.copy(center).addScaledVector(dir, dist);
  camera.near = dist / 100;
  camera.far = dist * 100;
  camera.updateProjectionMatrix();
  controls.update();
  return true;
}
window.addEventListener("keydown", (ev) => {
  if (ev.key === "f") fitToAvatars();
  if (ev.key === "r") fitCamera();
});

function objectsFromRoom(room: Room): void {
  for (const o of room.objects ?? []) {
    if (o && typeof o.object_id === "string" && typeof o.scene_index === "number") objectIds.set(o.object_id, o.scene_index);
  }
  // Names as the daemon loaded them (paths): the file name is enough on a label.
  sceneInfo.envNames = Array.isArray(room.environment) ? room.environment.map((n) => String(n).split("/").pop()!) : [];
}

const latestObjectPose = new Map<string, ObjectPose>();
function applyObjectPoses(): void {
  for (const [id, p] of latestObjectPose) {
    const mesh = objectMeshes.get(objectIds.get(id) ?? -1);
    if (!mesh || !isVec(p.position, 3) || !isVec(p.orientation, 4)) continue;
    mesh.visible = true;
    mesh.position.fromArray(p.position);
    const [w, x, y, z] = p.orientation;
    mesh.quaternion.set(x, y, z, w).normalize();
  }
  latestObjectPose.clear();
}

// ---- contacts: markers at witness points, labels, the strip ----
interface Marker { sprite: THREE.Sprite; label: HTMLDivElement; born: number; point: Vec3; info: ContactInfo; }
export interface ContactInfo { kind: "environment" | "shared"; client_id: string; pair: number; point: Vec3; text: string; seen_ms: number; }
const markerTexture = (() => {
  const c = document.createElement("canvas");
  c.width = c.height = 64;
  const g = c.getContext("2d")!;
  g.fillStyle = MARKER_COLOR;
  g.beginPath();
  g.arc(32, 32, 30, 0, 2 * Math.PI);
  g.fill();
  return new THREE.CanvasTexture(c);
})();
const markers: Marker[] = [];
const recentContacts: ContactInfo[] = [];
const allContacts: ContactInfo[] = [];
let holdMarkers = false;

function linkName(clientId: string, link: number): string {
  const names = avatars.get(clientId)?.client.link_name;
  return names && link >= 0 && link < names.length ? names[link] : `link ${link}`;
}

function addContact(info: ContactInfo): void {
  const mat = new THREE.SpriteMaterial({ map: markerTexture, color: 0xffffff, depthTest: false, depthWrite: false, transparent: true, sizeAttenuation: false });
  const sprite = new THREE.Sprite(mat);
  sprite.scale.set(0.035, 0.035, 1);
  sprite.position.fromArray(info.point);
  sprite.renderOrder = 10;
  scene.add(sprite);
  const label = document.createElement("div");
  label.textContent = info.text;
  labelsEl.appendChild(label);
  markers.push({ sprite, label, born: performance.now(), point: info.point, info });
  while (markers.length > 48) removeMarker(0);
  recentContacts.unshift(info);
  recentContacts.length = Math.min(recentContacts.length, STRIP_LENGTH);
  allContacts.push(info);
  if (allContacts.length > 1000) allContacts.splice(0, allContacts.length - 1000);
  stripEl.textContent = "recent contacts: ";
  for (const c of recentContacts) {
    const s = document.createElement("span");
    s.textContent = c.text;
    stripEl.appendChild(s);
  }
}

function removeMarker(i: number): void {
  const m = markers[i];
  scene.remove(m.sprite);
  m.sprite.material.dispose();
  m.label.remove();
  markers.splice(i, 1);
}

function onContact(e: ContactEvent): void {
  if (e.result !== 1 || !Array.isArray(e.contacts) || e.contacts.length === 0) return;
  const w = e.contacts[0];
  if (!w || !isVec(w.point_env, 3)) return;
  const env = sceneInfo.envNames[w.object] ?? `object ${w.object}`;
  addContact({
    kind: "environment",
    client_id: e.client_id,
    pair: e.pair,
    point: w.point_env,
    text: `${escapeForDisplay(e.client_id, 64)}.${escapeForDisplay(linkName(e.client_id, w.link), 64)} \u2194 ${escapeForDisplay(env, 64)}`,
    seen_ms: performance.now(),
  });
}

function onShared(s: SharedContact): void {
  for (const entry of Array.isArray(s.entries) ? s.entries : []) {
    if (entry.result !== 1 || !Array.isArray(entry.contacts) || entry.contacts.length === 0) continue;
    const w = entry.contacts[0];
    if (!w || !isVec(w.point_link, 3) || !isVec(w.point_other, 3)) continue;
    const other = entry.entity_kind === 0 ? `${entry.entity}.${linkName(entry.entity, w.other_link)}` : entry.entity;
    const p: Vec3 = [(w.point_link[0] + w.point_other[0]) / 2, (w.point_link[1] + w.point_other[1]) / 2, (w.point_link[2] + w.point_other[2]) / 2];
    addContact({
      kind: "shared",
      client_id: s.client_id,
      pair: s.pair,
      point: p,
      text: `${escapeForDisplay(s.client_id, 64)}.${escapeForDisplay(linkName(s.client_id, w.link), 64)} \u2194 ${escapeForDisplay(other, 130)}`,
      seen_ms: performance.now(),
    });
  }
}

function updateMarkers(now: number): void {
  for (let i = markers.length - 1; i >= 0; i--) {
    const m = markers[i];
    const age = now - m.born;
    if (!holdMarkers && age > MARKER_LIFE_MS) {
      removeMarker(i);
      continue;
    }
    const fade = holdMarkers ? 1 : 1 - age / MARKER_LIFE_MS;
    m.sprite.material.opacity = fade;
    const flash = holdMarkers ? 1 : 1 + 0.6 * Math.max(0, 1 - age / 250);
    m.sprite.scale.set(0.035 * flash, 0.035 * flash, 1);
    const px = project(m.point);
    m.label.style.left = `${px[0]}px`;
    m.label.style.top = `${px[1]}px`;
    m.label.style.opacity = String(fade);
    m.label.style.display = px[2] ? "" : "none";
  }
}

// ---- status: latency and rejections per client ----
let lastStatus: Status | null = null;
function renderClientTable(): void {
  const rows: HTMLTableRowElement[] = [];
  const s = lastStatus;
  const ids = new Set<string>([...avatars.keys(), ...(s?.client_id ?? [])]);
  for (const id of ids) {
    const tr = document.createElement("tr");
    const k = s ? s.client_id.indexOf(id) : -1;
    const ms = (v: number | undefined) => (typeof v === "number" && Number.isFinite(v) ? (v / 1000).toFixed(2) : "-");
    const a = avatars.get(id);
    const cells = [
      escapeForDisplay(id, 64),
      a?.door ?? "",
      k >= 0 ? `${ms(s!.latency_median_us[k])} / ${ms(s!.latency_p99_us[k])}` : "-",
      k >= 0 ? String(s!.rejected[k]) : "-",
      k >= 0 ? String(s!.rate_limited[k]) : "-",
    ];
    cells.forEach((text, i) => {
      const td = document.createElement("td");
      if (i === 0 && a) {
        const sw = document.createElement("span");
        sw.className = "swatch";
        sw.style.background = `#${a.color.getHexString()}`;
        td.appendChild(sw);
      }
      td.appendChild(document.createTextNode(text));
      tr.appendChild(td);
    });
    rows.push(tr);
  }
  clientsBody.replaceChildren(...rows);
}

// ---- the frame loop ----
function resize(): void {
  const w = canvas.clientWidth;
  const h = canvas.clientHeight;
  if (canvas.width !== Math.floor(w * renderer.getPixelRatio()) || canvas.height !== Math.floor(h * renderer.getPixelRatio())) {
    renderer.setSize(w, h, false);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
  }
}

const tmpP = new THREE.Vector3();
/** A world point's pixel on the canvas (CSS pixels from its top left); [2] false when behind the camera. */
function project(p: Vec3): [number, number, boolean] {
  tmpP.set(p[0], p[1], p[2]).project(camera);
  const rect = canvas.getBoundingClientRect();
  return [rect.left + ((tmpP.x + 1) / 2) * rect.width, rect.top + ((1 - tmpP.y) / 2) * rect.height, tmpP.z < 1 && tmpP.z > -1];
}

let frames = 0;
let fps = 0;
let fpsFrames = 0;
let fpsSince = performance.now();
function frame(now: number): void {
  requestAnimationFrame(frame); // first: a bad message must not stop the loop
  requestPoses();
  resize();
  applyPoses();
  applyObjectPoses();
  controls.update();
  updateMarkers(now);
  renderer.render(scene, camera);
  frames++;
  fpsFrames++;
  if (now - fpsSince >= 1000) {
    fps = (fpsFrames * 1000) / (now - fpsSince);
    fpsFrames = 0;
    fpsSince = now;
    updateStatusLine();
  }
}

// ---- the connection (in a worker: view/socket_worker.ts) ----
let posesReceived = 0;
let worker: Worker | null = null;
let hello: Hello | null = null;
let connState = "connecting";
let lastError = "";
function updateStatusLine(): void {
  statusEl.textContent = `SweptCCD live view: ${connState}${hello ? ` (${hello.security}, instance ${hello.instance})` : ""}` +
    ` | ${avatars.size} avatars | ${fps.toFixed(0)} fps${lastError ? " | " + lastError : ""}`;
}

function keyFromPage(): string | undefined {
  const params = new URLSearchParams(location.hash.slice(1));
  const fromHash = params.get("key");
  if (fromHash) {
    sessionStorage.setItem("sweptccd.room_key", fromHash);
    history.replaceState(null, "", location.pathname + location.search); // keep it out of the address bar
    return fromHash;
  }
  return sessionStorage.getItem("sweptccd.room_key") ?? undefined;
}

function onPose(p: TrackerPose): void {
  const a = avatars.get(p.client_id);
  if (!a || !Array.isArray(p.position) || p.position.length !== a.links || !Array.isArray(p.orientation) || p.orientation.length !== a.links) return;
  if (!p.position.every((v) => isVec(v, 3)) || !p.orientation.every((q) => isVec(q, 4))) return;
  a.latest = p; // applied at the next frame
  a.dirty = true;
}

let framePending = false;
/** Asks the worker for the latest poses (at most one request in flight). */
function requestPoses(): void {
  if (worker && !framePending) {
    framePending = true;
    worker.postMessage({ kind: "frame" });
  }
}

function start(key: string | undefined): void {
  const url = `${location.protocol === "https:" ? "wss:" : "ws:"}//${location.host}/ws`;
  worker?.terminate();
  worker = new Worker("./view_worker.js", { type: "module" });
  framePending = false;
  worker.onmessage = (ev: MessageEvent) => {
    const m = ev.data as { kind: string; name?: string; value?: unknown; poses?: TrackerPose[]; objects?: ObjectPose[]; received?: number; message?: string; code?: string };
    if (m.kind === "poses") {
      framePending = false;
      posesReceived = m.received ?? posesReceived;
      for (const p of m.poses ?? []) onPose(p);
      for (const p of m.objects ?? []) latestObjectPose.set(p.object_id, p);
    } else if (m.kind === "event") {
      const v = m.value;
      switch (m.name) {
        case "state": connState = String(v); updateStatusLine(); break;
        case "hello": hello = v as Hello; break;
        case "room": setRoom(v as Room); break;
        case "contact": onContact(v as ContactEvent); break;
        case "sharedContact": onShared(v as SharedContact); break;
        case "status": lastStatus = v as Status; renderClientTable(); break;
        case "serverError": {
          const e = v as { code: string; message: string };
          lastError = `${escapeForDisplay(String(e.code), 40)}: ${escapeForDisplay(String(e.message), 120)}`;
          updateStatusLine();
          break;
        }
      }
    } else if (m.kind === "failed") {
      lastError = escapeForDisplay(String(m.message), 160);
      if (m.code === "no_key" || m.code === "bad_proof") askKey();
      updateStatusLine();
    }
  };
  worker.onerror = (e) => { lastError = escapeForDisplay(`worker: ${e.message}`, 160); updateStatusLine(); };
  worker.postMessage({ kind: "start", url, key });
}

function askKey(): void {
  const form = document.getElementById("keyform") as HTMLFormElement;
  form.style.display = "block";
  form.onsubmit = (ev) => {
    ev.preventDefault();
    const text = (document.getElementById("keyinput") as HTMLInputElement).value.trim();
    try {
      parseKey(text);
    } catch (e) {
      lastError = (e as Error).message;
      updateStatusLine();
      return;
    }
    sessionStorage.setItem("sweptccd.room_key", text);
    form.style.display = "none";
    lastError = "";
    start(text);
  };
}

// ---- the test hook ----
export interface ViewHook {
  /** Frames per second over the last second, and frames drawn so far. */
  fps(): number;
  frames(): number;
  /** true once the scene is loaded and the viewer subscribed. */
  ready(): boolean;
  sceneError(): string;
  state(): string;
  /** A world point's canvas pixel (CSS px) and whether it is in front of the camera. */
  project(x: number, y: number, z: number): [number, number, boolean];
  /** Every avatar's id and the world midpoints of its capsules in the pose drawn (empty before one). */
  avatars(): { client_id: string; door: string; color: string; midpoints: Vec3[] }[];
  /** Contacts shown so far (oldest first, at most 1000), with their marker's pixel now. */
  contacts(): (ContactInfo & { pixel: [number, number, boolean] })[];
  /** Keep markers (no fading) for a screenshot; hide or show the environment meshes. */
  holdMarkers(on: boolean): void;
  showEnvironment(on: boolean): void;
  /** Hide or show the HTML panels and labels over the canvas. */
  showOverlays(on: boolean): void;
  /** Tracked objects: id, scene mesh, drawn or not (no pose yet), position and its pixel. */
  objects(): { object_id: string; scene_index: number; visible: boolean; position: Vec3; pixel: [number, number, boolean] }[];
  /** Points the camera at the avatars (false: none posed yet). */
  fitToAvatars(): boolean;
  /** Stop (or go on) applying new poses: the avatars stand still for a screenshot. */
  freezePoses(on: boolean): void;
  /** Poses received and poses applied to the instanced meshes. */
  counts(): { poses_received: number; poses_applied: number; avatars: number; markers: number };
  /** The background colour (RGB). */
  background: [number, number, number];
}
let sceneReady = false;
let sceneError = "";
const hook: ViewHook = {
  fps: () => fps,
  frames: () => frames,
  ready: () => sceneReady && connState === "ready",
  sceneError: () => sceneError,
  state: () => connState,
  project: (x, y, z) => project([x, y, z]),
  avatars: () =>
    [...avatars.entries()].map(([id, a]) => {
      const midpoints: Vec3[] = [];
      for (let i = 0; i < a.links; i++) {
        const e = linkEnds(a, i, true);
        if (e) midpoints.push([(e[0][0] + e[1][0]) / 2, (e[0][1] + e[1][1]) / 2, (e[0][2] + e[1][2]) / 2]);
      }
      return { client_id: id, door: a.door, color: `#${a.color.getHexString()}`, midpoints };
    }),
  contacts: () => allContacts.map((c) => ({ ...c, pixel: project(c.point) })),
  holdMarkers: (on) => { holdMarkers = on; },
  fitToAvatars: () => fitToAvatars(),
  freezePoses: (on) => { frozen = on; },
  objects: () =>
    [...objectIds.entries()].map(([id, index]) => {
      const mesh = objectMeshes.get(index);
      const p: Vec3 = mesh ? [mesh.position.x, mesh.position.y, mesh.position.z] : [0, 0, 0];
      return { object_id: id, scene_index: index, visible: !!mesh?.visible, position: p, pixel: project(p) };
    }),
  showEnvironment: (on) => { envGroup.visible = on; },
  showOverlays: (on) => {
    for (const el of [statusEl, document.getElementById("clients")!, stripEl, labelsEl]) el.style.visibility = on ? "" : "hidden";
  },
  counts: () => ({ poses_received: posesReceived, poses_applied: posesApplied, avatars: avatars.size, markers: markers.length }),
  background: [(BACKGROUND >> 16) & 255, (BACKGROUND >> 8) & 255, BACKGROUND & 255],
};
(window as unknown as { __sweptccdView: ViewHook }).__sweptccdView = hook;

loadScene()
  .then(() => { sceneReady = true; })
  .catch((e) => {
    sceneError = escapeForDisplay(String((e as Error).message), 160);
    lastError = sceneError;
    sceneReady = true; // the avatars still draw
  });
start(keyFromPage());
requestAnimationFrame(frame);
