// The example page: the JavaScript client in a browser, in a few lines.
import { LiveClient, Quat, RESULT, Vec3, escapeForDisplay } from "../src/index.js";

const logEl = document.getElementById("log")!;
const log = (line: string) => { logEl.textContent += line + "\n"; logEl.scrollTop = logEl.scrollHeight; };

document.getElementById("go")!.onclick = async () => {
  const key = (document.getElementById("key") as HTMLInputElement).value.trim() || undefined;
  const client = new LiveClient({
    url: `${location.protocol === "https:" ? "wss:" : "ws:"}//${location.host}/ws`,
    key,
    clientId: `example-${Math.floor(Math.random() * 1e6)}`,
    // SPEC section 1: an upper arm hanging from the shoulder, a forearm from the elbow.
    skeleton: {
      links: [
        { name: "upper_arm", parent: null, a: [0, 0, 0], b: [0.3, 0, 0], radius: 0.05 },
        { name: "forearm", parent: "upper_arm", a: [0, 0, 0], b: [0.28, 0, 0], radius: 0.04 },
      ],
    },
  });
  client.on("joined", ({ reply }) => log(`joined as ${reply.client_id}, session ${reply.session}`));
  client.on("contact", (e) => {
    if (e.result !== RESULT.CONTACT) return;
    const w = e.contacts[0];
    log(`pair ${e.pair}: contact at s [${e.s_lo.toFixed(4)}, ${e.s_hi.toFixed(4)}], ${client.skeleton.link_name[w.link]} at ${w.point_env.map((x) => x.toFixed(3))}`);
  });
  client.on("rejection", (r) => log(`rejected seq ${r.seq}: ${escapeForDisplay(r.reason)}: ${escapeForDisplay(r.message)}`));
  client.on("close", (c) => log(`connection closed (${c.code}), reconnecting in ${c.reconnectInMs} ms`));
  try {
    await client.connect();
  } catch (e) {
    log(`join failed: ${escapeForDisplay((e as Error).message)}`);
    return;
  }
  // The shoulder at 0.5 m; the arm swings from horizontal to straight down and
  // on, through the floor (z = 0) at the far end of the swing.
  const frames = 180;
  for (let k = 0; k < frames; k++) {
    const angle = (k / frames) * 1.4 * Math.PI;
    const q: Quat = [Math.cos(angle / 2), 0, Math.sin(angle / 2), 0]; // about y
    const shoulder: Vec3 = [0, 0, 0.5];
    const elbow: Vec3 = [0.3 * Math.cos(angle), 0, 0.5 - 0.3 * Math.sin(angle)];
    client.publishPose({ position: [shoulder, elbow], orientation: [q, q] });
    await new Promise((r) => setTimeout(r, 1000 / 60));
  }
  client.leave();
  log(`left: ${client.sentPoses} poses sent`);
};
