// Bundles the editor page's scripts (src/) and their CodeMirror and marked dependencies
// (node_modules/, pinned by package-lock.json) into bbzide/ui/static/dist/, which the IDE serves
// at /editor/dist/. Run by `make setup` after `npm ci`; the output is never committed.
import { build } from "esbuild";
import { fileURLToPath } from "node:url";

const here = fileURLToPath(new URL(".", import.meta.url));
await build({
  absWorkingDir: here,
  entryPoints: { editor: "src/editor.js", reference: "src/reference.js" },
  outdir: "../bbzide/ui/static/dist",
  bundle: true,
  format: "iife",
  minify: true,
  // Chromium, Firefox and Safari of the last years: CodeMirror 6's own floor.
  target: ["es2020"],
  legalComments: "linked",
  logLevel: "warning",
});
console.log("editor bundle: bbzide/ui/static/dist/{editor,reference}.js");
