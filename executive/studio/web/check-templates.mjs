// Validates Camunda element template files with @bpmn-io/element-templates-validator, the
// validator Camunda Modeler uses: `node check-templates.mjs FILE...`. A file is an array of
// templates; each is checked against the schema its `$schema` names (Camunda 7 or 8). Prints
// one JSON line per file ({file, templates, errors}) and exits 1 if any template is invalid.
// `TRACE_NODE_MODULES` names the node_modules to load the validator from.
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const modules = process.env.TRACE_NODE_MODULES || join(here, 'node_modules');
const require = createRequire(join(modules, '..', 'package.json'));
const { validateAll, validateAllZeebe } = require('@bpmn-io/element-templates-validator');

let bad = 0;
for (const file of process.argv.slice(2)) {
  const templates = JSON.parse(readFileSync(file, 'utf8'));
  const zeebe = templates.some(t => String(t.$schema || '').includes('zeebe'));
  const { valid, results } = (zeebe ? validateAllZeebe : validateAll)(templates);
  const errors = results.flatMap((r, i) =>
    (r.errors || []).map(e => ({ template: templates[i].id, message: e.message, path: e.dataPointer || e.instancePath })));
  if (!valid) bad += 1;
  console.log(JSON.stringify({ file, platform: zeebe ? 'c8' : 'c7', templates: templates.length, errors }));
}
process.exit(bad ? 1 : 0);
