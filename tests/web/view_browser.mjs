// The live view in Debian's headless Chromium (software WebGL: SwiftShader),
// driven by puppeteer-core, against the real daemon (view_browser.sh runs it
// in a private network namespace). Checks on screenshots:
//   1. one avatar ("known") plays the first pair of the bundled walk, a
//      contact (`sweptccd query` says so): the page shows that contact at
//      the client's witness point, and the screenshot has the marker's
//      colour at the pixel the page reports; the avatar's capsules are drawn
//      (non-background pixels where the page projects them) while a pixel
//      far from every avatar is background;
//   2. 16 more avatars stream the walk at 90 Hz for a few seconds: every one
//      is drawn, the page applied their poses; frames per second are logged
//      (never asserted: a timing).
//   3. in a second room with the shared world on (SHARED_BASE_URL), a tracked
//      object attached and posed: the page draws its mesh where it was put.
//   node view_browser.mjs BASE_URL KEY_FILE SKELETON POSES_30HZ EXPECTED POSES_90HZ WORK_DIR SHARED_BASE_URL
import assert from "node:assert/strict";
import { spawn } from "node:child_process";
import { readFileSync, writeFileSync } from "node:fs";
import { createRequire } from "node:module";
import path from "node:path";
import { pathToFileURL } from "node:url";
import { decodePng } from "./png.mjs";

const jsDir = process.env.SWEPTCCD_JS_DIR;
const lib = await import(pathToFileURL(path.join(jsDir, "dist", "node.js")).href);
const puppeteer = createRequire(path.join(jsDir, "package.json"))("puppeteer-core");
const [base, keyFile, skeletonFile, poses30File, expectedFile, poses90File, work, sharedBase] = process.argv.slice(2);
const key = readFileSync(keyFile, "utf8").trim();
const skeleton = JSON.parse(readFileSync(skeletonFile, "utf8"));
const poses30 = lib.parsePoseLines(readFileSync(poses30File, "utf8"));
const poses90 = lib.parsePoseLines(readFileSync(poses90File, "utf8"));
const expected = JSON.parse(readFileSync(expectedFile, "utf8").split("\n")[0]);
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const log = (...a) => console.log("view_browser:", ...a);
const url = base.replace(/^http/, "ws") + "/ws";
assert.equal(expected.result, "contact", "the walk's first pair must be a contact (sweptccd query)");

const browser = await puppeteer.launch({
  executablePath: "/usr/bin/chromium",
  headless: true,
  timeout: 20000,
  args: ["--headless=new", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
         `--user-data-dir=${path.join(work, "chromium-profile")}`],
});
const clients = [];
const children = [];
try {
  const page = await browser.newPage();
  const pageErrors = [];
  page.on("pageerror", (e) => pageErrors.push(e.message));
  page.on("console", (m) => { if (m.type() === "error") pageErrors.push(m.text()); });
  await page.setViewport({ width: 1024, height: 640, deviceScaleFactor: 1 });
  await page.goto(`${base}/#key=${key}`, { timeout: 15000 });
  await page.waitForFunction(() => window.__sweptccdView?.ready(), { timeout: 15000 });
  const sceneError = await page.evaluate(() => __sweptccdView.sceneError());
  assert.equal(sceneError, "", `the scene did not load: ${sceneError}`);
  log("page ready: subscribed, scene loaded");

  // 1. The known contact.
  const known = new lib.NodeLiveClient({ url, key, clientId: "known", skeleton });
  clients.push(known);
  const events = [];
  known.on("contact", (e) => events.push(e));
  await known.connect();
  await page.waitForFunction(() => __sweptccdView.avatars().some((a) => a.client_id === "known"), { timeout: 5000 });
  for (const [k, p] of poses30.slice(0, 2).entries()) known.publishPose({ utime: p.utime, seq: k, position: p.position, orientation: p.orientation });
  for (let t = 0; events.length < 1 && t < 10000; t += 10) await sleep(10);
  assert.equal(events.length, 1, "no event for the known pair");
  const ev = events[0];
  assert.equal(ev.result, 1);
  assert.equal(ev.s_lo, expected.s_lo);
  const witness = ev.contacts[0].point_env;
  for (let i = 0; i < 3; i++) assert.ok(Math.abs(witness[i] - expected.contacts[0].point_env[i]) < 1e-6, "the daemon's witness is not the query's");
  await page.waitForFunction(() => __sweptccdView.contacts().some((c) => c.client_id === "known" && c.pair === 0), { timeout: 5000 });
  await page.waitForFunction(() => __sweptccdView.fitToAvatars(), { timeout: 5000 });
  await page.evaluate(() => { __sweptccdView.holdMarkers(true); __sweptccdView.showEnvironment(false); __sweptccdView.showOverlays(false); });
  const f0 = await page.evaluate(() => __sweptccdView.frames());
  await page.waitForFunction((f) => __sweptccdView.frames() > f + 2, { timeout: 10000 }, f0);
  const state1 = await page.evaluate(() => ({ contacts: __sweptccdView.contacts(), avatars: __sweptccdView.avatars(), background: __sweptccdView.background,
    project: (() => { const a = __sweptccdView.avatars().find((x) => x.client_id === "known"); return a.midpoints.map((m) => __sweptccdView.project(...m)); })() }));
  const shot1 = await page.screenshot({ type: "png" });
  writeFileSync(path.join(work, "known_contact.png"), shot1);
  const img1 = decodePng(Buffer.from(shot1));
  const bg = state1.background;
  const isBackground = (px) => Math.abs(px[0] - bg[0]) < 12 && Math.abs(px[1] - bg[1]) < 12 && Math.abs(px[2] - bg[2]) < 12;
  const onCanvas = ([x, y, front]) => front && x >= 2 && y >= 2 && x < img1.width - 2 && y < img1.height - 2;
  const contact = state1.contacts.find((c) => c.client_id === "known" && c.pair === 0);
  for (let i = 0; i < 3; i++) assert.equal(contact.point[i], witness[i], "the page's contact point is not the event's witness");
  assert.match(contact.text, /^known\.[A-Za-z0-9_]+ \u2194 /, `label ${contact.text}`);
  assert.ok(onCanvas(contact.pixel), `the contact projects off the canvas: ${contact.pixel}`);
  const mark = img1.pixel(contact.pixel[0], contact.pixel[1]);
  assert.ok(mark[0] > 180 && mark[1] < 90 && mark[2] > 180, `no marker colour at the reported pixel ${contact.pixel.map(Math.round)}: ${mark}`);
  log(`known contact: ${contact.text} at pixel ${contact.pixel.slice(0, 2).map(Math.round)}, colour ${mark}`);
  const pts = state1.project.filter(onCanvas);
  assert.ok(pts.length >= 10, `the known avatar is mostly off the canvas (${pts.length} midpoints on it)`);
  const drawn = pts.filter((p) => !isBackground(img1.pixel(p[0], p[1]))).length;
  assert.ok(drawn >= 0.8 * pts.length, `the known avatar is not drawn: ${drawn} of ${pts.length} capsule midpoints off the background`);
  // A control: the pixel farthest from every capsule and the marker is background.
  let far = null;
  for (let y = 20; y < img1.height - 20; y += 16) {
    for (let x = 20; x < img1.width - 20; x += 16) {
      const d = Math.min(...[...pts, contact.pixel].map((p) => Math.hypot(p[0] - x, p[1] - y)));
      if (!far || d > far.d) far = { x, y, d };
    }
  }
  assert.ok(far.d > 100 && isBackground(img1.pixel(far.x, far.y)), `control pixel ${far.x},${far.y} not background: ${img1.pixel(far.x, far.y)}`);
  log(`known avatar: ${drawn} of ${pts.length} capsule midpoints drawn; control pixel (${far.x}, ${far.y}) background`);

  // The WebXR page's headset-free mode: the walk's first 30 poses through the
  // page's streamer; every pair answered, as many contacts as the query has.
  const xr = await browser.newPage();
  xr.on("pageerror", (e) => pageErrors.push(`xr.html: ${e.message}`));
  await xr.goto(`${base}/xr.html#key=${key}&id=xrreplay`, { timeout: 15000 });
  await xr.waitForFunction(() => window.__sweptccdXr, { timeout: 10000 });
  const lines = readFileSync(poses30File, "utf8").split("\n").filter((l) => l.trim()).slice(0, 30).join("\n");
  const replayed = await xr.evaluate((sk, ps) => window.__sweptccdXr.replay(sk, ps, 1), readFileSync(skeletonFile, "utf8"), lines);
  assert.equal(replayed, 30);
  // The daemon may skip pairs when it is behind (latest-wins): the answers
  // chain seq 0 to 29, and every consecutive pair equals the query's.
  await xr.waitForFunction(() => window.__sweptccdXr.answers().some((a) => a.seq1 === 29), { timeout: 10000 }).catch(async (e) => {
    log(`xr.html stats: ${JSON.stringify(await xr.evaluate(() => window.__sweptccdXr.stats()))}`);
    throw e;
  });
  const xrStats = await xr.evaluate(() => window.__sweptccdXr.stats());
  const answers = await xr.evaluate(() => window.__sweptccdXr.answers());
  const want = readFileSync(expectedFile, "utf8").split("\n").filter((l) => l.trim()).map((l) => JSON.parse(l));
  assert.equal(xrStats.sent, 30);
  assert.equal(xrStats.rejections, 0);
  let chain = 0, compared = 0, skipped = 0;
  for (const a of answers) {
    assert.equal(a.seq0, chain, `xr.html replay: the answers do not chain at seq ${chain}`);
    chain = a.seq1;
    if (a.seq1 !== a.seq0 + 1) { skipped += a.seq1 - a.seq0 - 1; continue; }
    const w = want[a.seq0];
    assert.equal(a.result, { free: 0, contact: 1, invalid: 2 }[w.result], `xr.html replay pair ${a.seq0}: result`);
    if (w.result === "contact") assert.deepEqual([a.s_lo, a.s_hi], [w.s_lo, w.s_hi], `xr.html replay pair ${a.seq0}`);
    compared++;
  }
  assert.equal(chain, 29);
  assert.ok(compared >= 15, `xr.html replay: only ${compared} pairs answered unskipped`);
  await xr.evaluate(() => window.__sweptccdXr.leave());
  await xr.close();
  log(`xr.html replay: 30 poses through the page's streamer, ${answers.length} events (${skipped} pairs skipped by the daemon's latest-wins), ${compared} equal to sweptccd query`);

  // 2. 16 avatars at 90 Hz.
  await page.evaluate(() => { __sweptccdView.holdMarkers(false); __sweptccdView.showEnvironment(true); __sweptccdView.showOverlays(true); });
  const load = [];
  for (let i = 0; i < 16; i++) {
    const c = new lib.NodeLiveClient({ url, key, clientId: `load${i}`, skeleton });
    clients.push(c);
    load.push(c);
  }
  await Promise.all(load.map((c) => c.connect()));
  // An avatar through the LCM door, in the same room.
  const lcm = spawn(process.env.SWEPTCCD_BIN, ["simulate-tracker", "--lcm-url", process.env.SWEPTCCD_LCM_URL, "--poses", poses30File,
    "--skeleton", skeletonFile, "--join", "--key", keyFile, "--client", "lcmwalker", "--offset", "2.4", "0", "0", "--loop", "0",
    "--rebase-utime", "--duration", "30"], { stdio: ["ignore", "ignore", "pipe"] });
  let lcmErr = "";
  lcm.stderr.on("data", (d) => { lcmErr += d; });
  children.push(lcm);
  await page.waitForFunction(() => __sweptccdView.avatars().some((a) => a.client_id === "lcmwalker" && a.door === "lcm" && a.midpoints.length > 0), { timeout: 10000 })
    .catch((e) => { throw new Error(`no lcmwalker in the view (${e.message}); simulate-tracker: ${lcmErr.slice(0, 300)}`); });
  await page.waitForFunction(() => __sweptccdView.avatars().length >= 17, { timeout: 10000 });
  const counts0 = await page.evaluate(() => __sweptccdView.counts());
  const seconds = Number(process.env.VIEW_LOAD_SECONDS || 6);
  const period = 1000 / 90;
  const t0 = Date.now();
  const fpsLog = [];
  let k = 0;
  let nextFps = t0 + 1000;
  while (Date.now() - t0 < seconds * 1000) {
    const p = poses90[k % poses90.length];
    const utime = poses90[0].utime + Math.round(k * period * 1000);
    load.forEach((c, i) => {
      const dx = (i % 4) * 0.7 - 1.0, dy = Math.floor(i / 4) * 0.7 - 1.0;
      c.publishPose({ utime, seq: k, position: p.position.map((q) => [q[0] + dx, q[1] + dy, q[2]]), orientation: p.orientation });
    });
    k++;
    if (Date.now() >= nextFps) {
      fpsLog.push(await page.evaluate(() => __sweptccdView.fps()));
      nextFps += 1000;
    }
    await sleep(Math.max(0, t0 + k * period - Date.now()));
  }
  // A client the daemon closed (slow_reader: this process could not read its
  // answers in time on a busy machine) has re-joined by itself: one more pose
  // each, so every avatar has a pose to draw.
  const rejoins = load.reduce((n, c) => n + c.rejoins, 0);
  for (let t = 0; !load.every((c) => c.joined) && t < 10000; t += 20) await sleep(20);
  const p = poses90[k % poses90.length];
  load.forEach((c, i) => {
    const dx = (i % 4) * 0.7 - 1.0, dy = Math.floor(i / 4) * 0.7 - 1.0;
    c.publishPose({ utime: poses90[0].utime + Math.round(k * period * 1000), seq: k, position: p.position.map((q) => [q[0] + dx, q[1] + dy, q[2]]), orientation: p.orientation });
  });
  await page.waitForFunction(() => __sweptccdView.avatars().filter((a) => a.client_id.startsWith("load") && a.midpoints.length > 0).length === 16, { timeout: 10000 });
  const counts1 = await page.evaluate(() => __sweptccdView.counts());
  const sent = load.reduce((n, c) => n + c.sentPoses, 0);
  const sorted = [...fpsLog].sort((a, b) => a - b);
  log(`16 avatars at 90 Hz for ${seconds} s (+1 still, +1 over LCM at 30 Hz): ${sent} poses sent, page received ${counts1.poses_received - counts0.poses_received}` +
      ` (latest-wins forwarding), applied ${counts1.poses_applied - counts0.poses_applied}; fps per second ${fpsLog.map((f) => f.toFixed(1)).join(" ")}` +
      ` (median ${sorted[Math.floor(sorted.length / 2)]?.toFixed(1)}, min ${sorted[0]?.toFixed(1)}; SwiftShader on this machine's CPUs, logged, not asserted); ${rejoins} re-joins`);
  assert.ok(counts1.poses_applied > counts0.poses_applied + 16, "the page applied no poses of the 16 avatars");
  await page.evaluate(() => { __sweptccdView.freezePoses(true); __sweptccdView.fitToAvatars(); __sweptccdView.showEnvironment(false); __sweptccdView.showOverlays(false); });
  const f1 = await page.evaluate(() => __sweptccdView.frames());
  await page.waitForFunction((f) => __sweptccdView.frames() > f + 2, { timeout: 10000 }, f1);
  const state2 = await page.evaluate(() => __sweptccdView.avatars().map((a) => ({ id: a.client_id, px: a.midpoints.map((m) => __sweptccdView.project(...m)) })));
  const shot2 = await page.screenshot({ type: "png" });
  writeFileSync(path.join(work, "sixteen_avatars.png"), shot2);
  const img2 = decodePng(Buffer.from(shot2));
  // (known, silent since its two poses, may have been dropped by the silence timeout.)
  const loaded = state2.filter((a) => a.id.startsWith("load") || a.id === "lcmwalker");
  assert.equal(loaded.length, 17, "the room lost streaming avatars");
  for (const a of loaded) {
    const on = a.px.filter(onCanvas);
    assert.ok(on.length >= 10, `${a.id}: ${on.length} capsule midpoints on the canvas`);
    const hit = on.filter((p) => !isBackground(img2.pixel(p[0], p[1]))).length;
    assert.ok(hit >= 0.8 * on.length, `${a.id}: only ${hit} of ${on.length} capsule midpoints drawn`);
  }
  log(`all ${loaded.length} streaming avatars drawn in the screenshot (16 WebSocket, 1 LCM)`);
  // 3. A tracked object in the shared-world room.
  // A tracked object: attached with its proof (the room key), posed beside
  // the known avatar; the page draws its scene mesh there.
  const page2 = await browser.newPage();
  page2.on("pageerror", (e) => pageErrors.push(`shared room: ${e.message}`));
  await page2.setViewport({ width: 1024, height: 640, deviceScaleFactor: 1 });
  await page2.goto(`${sharedBase}/#key=${key}`, { timeout: 15000 });
  await page2.waitForFunction(() => window.__sweptccdView?.ready(), { timeout: 15000 });
  const box = new lib.NodeObjectTracker({ url: sharedBase.replace(/^http/, "ws") + "/ws", key, objectId: "box" });
  clients.push(box);
  await box.connect();
  const beside = [poses30[1].position[0][0] + 0.6, poses30[1].position[0][1], poses30[1].position[0][2]];
  assert.ok(box.publishPose({ position: beside, orientation: [1, 0, 0, 0] }));
  await page2.waitForFunction(() => __sweptccdView.objects().some((o) => o.object_id === "box" && o.visible), { timeout: 5000 });
  await page2.evaluate(() => { __sweptccdView.showEnvironment(false); __sweptccdView.showOverlays(false); });
  const f2 = await page2.evaluate(() => __sweptccdView.frames());
  await page2.waitForFunction((f) => __sweptccdView.frames() > f + 2, { timeout: 10000 }, f2);
  const obj = (await page2.evaluate(() => __sweptccdView.objects())).find((o) => o.object_id === "box");
  assert.deepEqual(obj.position, beside);
  const shot3 = await page2.screenshot({ type: "png" });
  writeFileSync(path.join(work, "tracked_object.png"), shot3);
  const img3 = decodePng(Buffer.from(shot3));
  assert.ok(onCanvas(obj.pixel), `the box projects off the canvas: ${obj.pixel}`);
  const boxPx = img3.pixel(obj.pixel[0], obj.pixel[1]);
  assert.ok(!isBackground(boxPx), `the tracked object is not drawn at ${obj.pixel.map(Math.round)}: ${boxPx}`);
  // A control: 60 px beside it, background.
  const side = img3.pixel(Math.min(obj.pixel[0] + 60, img3.width - 1), obj.pixel[1]);
  assert.ok(isBackground(side), `beside the box is not background: ${side}`);
  log(`shared-world room: tracked object box drawn at pixel ${obj.pixel.slice(0, 2).map(Math.round)} (colour ${boxPx}), background beside it`);
  box.close();
  await page2.close();

  assert.deepEqual(pageErrors, [], "the page reported errors");
} finally {
  for (const c of children) c.kill("SIGTERM");
  for (const c of clients) c.close();
  await browser.close();
}
log("passed");
