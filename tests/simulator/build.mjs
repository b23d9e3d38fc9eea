// Bundles the differential test's page (simulate.js and index.html) with esbuild into OUTDIR:
// `node build.mjs OUTDIR`. `TRACE_NODE_MODULES` names the studio's installed packages
// (executive/studio/web/package-lock.json pins bpmn-js and bpmn-js-token-simulation there).
import { copyFileSync, mkdirSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const out = process.argv[2];
const modules = process.env.TRACE_NODE_MODULES;
if (!out || !modules) {
  console.error('usage: TRACE_NODE_MODULES=DIR node build.mjs OUTDIR');
  process.exit(2);
}
const { build } = createRequire(join(modules, '..', 'package.json'))('esbuild');

mkdirSync(out, { recursive: true });
await build({
  entryPoints: [join(here, 'simulate.js')],
  bundle: true,
  format: 'iife',
  outdir: out,
  nodePaths: [modules],
  logLevel: 'warning',
});
copyFileSync(join(here, 'index.html'), join(out, 'index.html'));
