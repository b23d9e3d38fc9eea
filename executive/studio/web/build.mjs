// Bundles TRACE Studio's page with esbuild: `node build.mjs OUTDIR` (default `dist`).
// `TRACE_NODE_MODULES` names the node_modules to resolve packages from (the crate's build.rs
// installs them outside the source tree); otherwise the one beside this file.
import { copyFileSync, mkdirSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const out = process.argv[2] || join(here, 'dist');
const modules = process.env.TRACE_NODE_MODULES || join(here, 'node_modules');
// esbuild itself comes from those node_modules too.
const { build } = createRequire(join(modules, '..', 'package.json'))('esbuild');

mkdirSync(out, { recursive: true });
await build({
  entryPoints: [join(here, 'src/app.js')],
  bundle: true,
  minify: true,
  format: 'iife',
  outdir: out,
  nodePaths: [modules],
  jsx: 'automatic',
  jsxImportSource: '@bpmn-io/properties-panel/preact',
  loader: { '.woff2': 'file', '.woff': 'file', '.ttf': 'file', '.eot': 'file', '.svg': 'file' },
  assetNames: '[name]',
  logLevel: 'warning',
});
copyFileSync(join(here, 'src/index.html'), join(out, 'index.html'));
