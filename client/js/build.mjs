// Bundles the pages (live view, WebXR pose source, example page) with
// esbuild into OUT_DIR: one self-contained .js per page (three.js and the
// client library inside), the HTML beside it. Nothing is fetched at run
// time but the daemon's own /scene.json, /scene/N.bin and /ws.
//   node build.mjs OUT_DIR
import { build } from "esbuild";
import { copyFileSync, mkdirSync } from "node:fs";
import path from "node:path";
import { fileURLToPath } from "node:url";

const here = path.dirname(fileURLToPath(import.meta.url));
const out = process.argv[2];
if (!out) {
  console.error("usage: node build.mjs OUT_DIR");
  process.exit(2);
}
mkdirSync(out, { recursive: true });
const pages = [
  { entry: "view/main.ts", js: "view.js", html: "view/index.html" },
  { entry: "view/socket_worker.ts", js: "view_worker.js" },
  { entry: "xr/xr_page.ts", js: "xr.js", html: "xr/xr.html" },
  { entry: "examples/example_page.ts", js: "example.js", html: "examples/example.html" },
];
for (const page of pages) {
  await build({
    entryPoints: [path.join(here, page.entry)],
    outfile: path.join(out, page.js),
    bundle: true,
    format: "esm",
    platform: "browser",
    target: ["es2020"],
    minify: true,
    sourcemap: false,
    legalComments: "linked",
    logLevel: "warning",
  });
  if (page.html) copyFileSync(path.join(here, page.html), path.join(out, path.basename(page.html)));
}
console.log(`build.mjs: ${pages.length} pages in ${out}`);
