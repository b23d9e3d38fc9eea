// TRACE Studio's page: bpmn-js Modeler with the properties panel and TRACE's own panel
// (provider.jsx), the mission files of the studio's directory, and the executive's diagnostics
// (the same as `trace validate`) on the elements and in a list, checked as the model changes;
// verification with its counterexamples replayed (verify.js), the token game (simulate.js), and
// the running missions followed live (ops.js).
import BpmnModeler from 'bpmn-js/lib/Modeler';
import { BpmnPropertiesPanelModule, BpmnPropertiesProviderModule } from 'bpmn-js-properties-panel';
import zeebeModdle from 'zeebe-bpmn-moddle/resources/zeebe.json';
import 'bpmn-js/dist/assets/diagram-js.css';
import 'bpmn-js/dist/assets/bpmn-js.css';
import 'bpmn-js/dist/assets/bpmn-font/css/bpmn.css';
import '@bpmn-io/properties-panel/dist/assets/properties-panel.css';
import './style.css';
import traceModdle from './trace-moddle.json';
import TracePanelModule, { traceTask } from './provider.jsx';
import DrawingModule from './drawing.jsx';
import { setupVerify } from './verify.js';
import { setupSimulate } from './simulate.js';
import { setupOps } from './ops.js';
import { setupRecord } from './record.js';

// Every error the page meets, for the operator's console and for tests to read.
const errors = [];
window.addEventListener('error', e => errors.push(String(e.message)));
window.addEventListener('unhandledrejection', e => errors.push(String(e.reason)));

/** The actions of every catalogue the studio knows, filled before the first import. */
const catalogue = {
  actions: [],
  action(name) { return this.actions.find(a => a.name === name); },
};

/** The last check's diagnostics: the panel lists the selected element's (drawing.jsx) and
 * marks each on the field it is in, so the panel and the problem list say the same. */
const problems = {
  diagnostics: [],
  of(id) { return this.diagnostics.filter(d => d.element === id); },
};

/** The processes of the files the open one imports (a call activity may call them). */
const imported = { processes: [] };

const modeler = new BpmnModeler({
  container: '#canvas',
  propertiesPanel: { parent: '#panel' },
  additionalModules: [
    BpmnPropertiesPanelModule,
    BpmnPropertiesProviderModule,
    TracePanelModule,
    DrawingModule,
    { traceCatalogue: ['value', catalogue], traceProblems: ['value', problems],
      traceImports: ['value', imported] },
  ],
  moddleExtensions: { trace: traceModdle, zeebe: zeebeModdle },
});

const $ = id => document.getElementById(id);
let current = null;   // the open file's name
const verification = setupVerify({ modeler, api, say, current: () => current });
const simulation = setupSimulate({ modeler, api, say });
const ops = setupOps({ api, say });
const recording = setupRecord({ modeler, api, say });
let dirty = false;
let checking = null;  // the pending check's timer

function say(text, kind = '') {
  $('status').textContent = text;
  $('status').className = kind;
}

async function api(path, options = {}) {
  const res = await fetch(path, options);
  const body = await res.text();
  if (!res.ok) {
    let why = body;
    try { why = JSON.parse(body).error || body; } catch (_) { /* plain text */ }
    throw new Error(`${res.status}: ${why}`);
  }
  return body;
}

async function listMissions(select) {
  const files = JSON.parse(await api('/api/missions'));
  const box = $('missions');
  box.replaceChildren(...files.map(f => new Option(f.name, f.name)));
  if (select) box.value = select;
  return files;
}

async function open(name) {
  const xml = await api(`/api/missions/${encodeURIComponent(name)}`);
  await show(name, xml);
}

/** Lists the file's diagrams (one per process, or the collaboration) to switch between. */
function listDiagrams() {
  const diagrams = modeler.getDefinitions().diagrams || [];
  const label = d => {
    const e = d.plane && d.plane.bpmnElement;
    return (e && (e.name || e.id)) || d.name || d.id;
  };
  const box = $('diagrams');
  box.replaceChildren(...diagrams.map(d => new Option(label(d), d.id)));
  box.hidden = diagrams.length < 2;
  const shown = modeler.get('canvas').getRootElement().businessObject;
  const now = diagrams.find(d => d.plane && d.plane.bpmnElement === shown);
  if (now) {
    box.value = now.id;
    document.body.dataset.diagram = now.id;
  }
}

/** Shows diagram `id` of the open file, fitted, and its problems. */
async function openDiagram(id) {
  await modeler.open(id);
  fitView();
  $('diagrams').value = id;
  document.body.dataset.diagram = id;
  // A game being played goes on: its tokens drawn on this diagram's elements.
  simulation.redraw();
  await check();
}

/** A free id with this prefix in the open file. */
function freeId(prefix) {
  const taken = new Set();
  const walk = o => {
    if (!o || typeof o !== 'object' || taken.has(o)) return;
    if (typeof o.id === 'string') taken.add(o.id);
    for (const k of Object.keys(o)) if (!k.startsWith('$')) {
      const v = o[k];
      if (Array.isArray(v)) v.forEach(walk); else if (v && typeof v === 'object' && v.$type) walk(v);
    }
  };
  walk(modeler.getDefinitions());
  let n = 1;
  while (taken.has(`${prefix}_${n}`)) n += 1;
  return `${prefix}_${n}`;
}

/** A new process in the open file (asked for its name), with a start event and a diagram of
 * its own, opened: what a call activity can then call. */
async function newProcess() {
  const name = prompt('Name of the new process', 'Subtask');
  if (name === null) return;
  const moddle = modeler.get('moddle');
  const defs = modeler.getDefinitions();
  const id = freeId('Process');
  const process = moddle.create('bpmn:Process', { id, name: name.trim() || id, isExecutable: true });
  const start = moddle.create('bpmn:StartEvent', { id: freeId('Start'), name: 'Start' });
  start.$parent = process;
  process.get('flowElements').push(start);
  process.$parent = defs;
  defs.get('rootElements').push(process);
  const shape = moddle.create('bpmndi:BPMNShape', {
    id: `${start.id}_di`, bpmnElement: start,
    bounds: moddle.create('dc:Bounds', { x: 180, y: 160, width: 36, height: 36 }),
  });
  const plane = moddle.create('bpmndi:BPMNPlane', { id: `${id}_plane`, bpmnElement: process, planeElement: [shape] });
  const diagram = moddle.create('bpmndi:BPMNDiagram', { id: `${id}_diagram`, plane });
  diagram.$parent = defs;
  defs.get('diagrams').push(diagram);
  // Read again from its text, so the new diagram is one bpmn-js knows.
  const { xml } = await modeler.saveXML({ format: true });
  await modeler.importXML(xml, diagram.id);
  dirty = true;
  simulation.stop();
  listDiagrams();
  await openDiagram(diagram.id);
  say(`${current}: process ${process.name} added (${id})`, 'ok');
}

function fitView() {
  const canvas = modeler.get('canvas');
  canvas.zoom('fit-viewport');
  // The palette covers the canvas's left edge: leave it room.
  const box = canvas.viewbox();
  canvas.viewbox({ x: box.x - 80, y: box.y, width: box.width + 80, height: box.height });
}

const BPMN_MODEL = 'http://www.omg.org/spec/BPMN/20100524/MODEL';

/** Reads the processes of the BPMN files `definitions` imports, and of theirs (plain file
 * names of the mission directory, at most 20 files), for the called-process list. */
async function readImports(definitions) {
  const found = [];
  const seen = new Set([current]);
  const queue = (definitions.get('imports') || []).map(i => i.location);
  while (queue.length && seen.size <= 20) {
    const file = queue.shift();
    if (!file || seen.has(file) || !/^[A-Za-z0-9][A-Za-z0-9._-]*\.bpmn$/.test(file)) continue;
    seen.add(file);
    let doc;
    try {
      doc = new DOMParser().parseFromString(await api(`/api/missions/${encodeURIComponent(file)}`), 'application/xml');
    } catch (e) {
      say(`${file} (imported): ${e.message}`, 'warn');
      continue;
    }
    for (const p of doc.getElementsByTagNameNS(BPMN_MODEL, 'process')) {
      found.push({ id: p.getAttribute('id'), name: p.getAttribute('name') || '', file });
    }
    for (const i of doc.getElementsByTagNameNS(BPMN_MODEL, 'import')) {
      if (i.getAttribute('importType') === BPMN_MODEL) queue.push(i.getAttribute('location'));
    }
  }
  imported.processes = found;
}

async function show(name, xml) {
  const { warnings } = await modeler.importXML(xml);
  imported.processes = [];
  current = name;
  dirty = false;
  $('missions').value = name;
  listDiagrams();
  fitView();
  say(warnings.length ? `${name}: opened with ${warnings.length} import warnings` : `${name}: opened`);
  simulation.stop();
  await readImports(modeler.getDefinitions());
  await verification.loadRequirements(name);
  await check();
}

const EMPTY = `<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:bpmndi="http://www.omg.org/spec/BPMN/20100524/DI" xmlns:dc="http://www.omg.org/spec/DD/20100524/DC" xmlns:trace="urn:trace:bpmn:1.0" id="Definitions" targetNamespace="urn:trace:missions">
  <bpmn:process id="Mission" isExecutable="true">
    <bpmn:startEvent id="Start" name="Start"/>
  </bpmn:process>
  <bpmndi:BPMNDiagram id="Diagram">
    <bpmndi:BPMNPlane id="Plane" bpmnElement="Mission">
      <bpmndi:BPMNShape id="Start_di" bpmnElement="Start"><dc:Bounds x="180" y="160" width="36" height="36"/></bpmndi:BPMNShape>
    </bpmndi:BPMNPlane>
  </bpmndi:BPMNDiagram>
</bpmn:definitions>`;

/** A new mission: its file name asked for (a plain name, `.bpmn` added), unsaved edits kept
 * unless the planner lets them go. */
async function create(ask = true) {
  if (dirty && !confirm(`Leave ${current} without saving?`)) return;
  const taken = new Set([...$('missions').options].map(o => o.value));
  let n = 1;
  while (taken.has(`mission-${n}.bpmn`)) n += 1;
  // An empty directory opens on a new mission at once: nothing to ask yet.
  const asked = ask ? prompt('Name of the new mission file', `mission-${n}.bpmn`) : `mission-${n}.bpmn`;
  if (asked === null) return;
  let name = asked.trim();
  if (!name.endsWith('.bpmn')) name += '.bpmn';
  if (!/^[A-Za-z0-9][A-Za-z0-9._-]*\.bpmn$/.test(name)) {
    say(`${name}: a file name is letters, digits, '.', '_' and '-'`, 'bad');
    return;
  }
  if (taken.has(name)) {
    say(`${name} exists: open it from the list`, 'bad');
    return;
  }
  $('missions').append(new Option(name, name));
  await show(name, EMPTY);
  dirty = true;
}

async function save() {
  if (!current) return;
  const { xml } = await modeler.saveXML({ format: true });
  try {
    await api(`/api/missions/${encodeURIComponent(current)}`, {
      method: 'PUT', headers: { 'Content-Type': 'application/xml' }, body: xml,
    });
    dirty = false;
    say(`${current}: saved`, 'ok');
    document.body.dataset.saved = current;
  } catch (e) {
    say(`${current}: not saved — ${e.message}`, 'bad');
  }
}

/** What the check against the systems' catalogues covered, for the verdict line. */
function fit(c) {
  if (!c || !c.checked) return '';
  const missing = c.missing.length ? `; no catalogue for ${c.missing.join(', ')}` : '';
  if (c.mismatches) return `; ${c.mismatches} catalogue mismatches (trace run would refuse)${missing}`;
  return `; fits the catalogues of ${c.servers.join(', ') || 'no system'}${missing}`;
}

/** Validates the model as it is now and shows every diagnostic. */
async function check() {
  // Formatted as saved, so that each problem's line is the saved file's.
  const { xml } = await modeler.saveXML({ format: true });
  let report;
  try {
    report = JSON.parse(await api('/api/validate', {
      method: 'POST', headers: { 'Content-Type': 'application/xml' }, body: xml,
    }));
  } catch (e) {
    say(`cannot check: ${e.message}`, 'bad');
    return;
  }
  const registry = modeler.get('elementRegistry');
  const canvas = modeler.get('canvas');
  const overlays = modeler.get('overlays');
  overlays.remove({ type: 'trace-diagnostic' });
  for (const el of registry.getAll()) {
    canvas.removeMarker(el, 'trace-error');
    canvas.removeMarker(el, 'trace-warning');
  }
  const items = [];
  const root = canvas.getRootElement();
  for (const d of report.diagnostics) {
    const el = d.element && registry.get(d.element);
    const kind = d.severity === 'error' ? 'error' : 'warning';
    // A process-level problem is listed, not painted over the whole diagram.
    if (el && el !== root) {
      canvas.addMarker(el, `trace-${kind}`);
      const badge = document.createElement('div');
      badge.className = `trace-badge trace-badge-${kind}`;
      badge.title = `${d.code}: ${d.message}`;
      badge.textContent = kind === 'error' ? '!' : '?';
      overlays.add(el, 'trace-diagnostic', { position: { top: -10, right: 10 }, html: badge });
    }
    const li = document.createElement('li');
    li.className = `problem ${kind}`;
    li.dataset.element = d.element || '';
    li.dataset.code = d.code;
    const bo = el && el.businessObject;
    const where = bo && bo.name ? `\`${bo.name}\`` : d.element;
    li.textContent = `${kind} ${d.code}${where ? ` at ${where}` : ''} (line ${d.line}): ${d.message}`;
    if (el && el !== root) li.addEventListener('click', () => {
      modeler.get('selection').select(el);
      canvas.scrollToElement(el);
    });
    items.push(li);
  }
  $('problems').replaceChildren(...items);
  problems.diagnostics = report.diagnostics;
  markFields();
  modeler.get('eventBus').fire('trace.checked');
  $('verdict').textContent = `— ${report.verdict}, ${report.diagnostics.length} diagnostics${fit(report.catalogue)}`;
  document.body.dataset.verdict = report.verdict;
  document.body.dataset.mismatches = String(report.catalogue ? report.catalogue.mismatches : 0);
  document.body.dataset.checks = String(Number(document.body.dataset.checks || 0) + 1);
}

/** The panel entry a diagnostic's `field` names on element `el`, if the panel shows one. */
function entryOf(el, d) {
  const [kind, path] = d.field.split(/:(.*)/s);
  if (kind === 'condition') return 'trace-condition-expr';
  if (kind === 'resource') return 'trace-resource';
  if (kind !== 'input' && kind !== 'output') return undefined;
  const task = traceTask(el);
  if (!task) return undefined;
  const goal = kind === 'input';
  const i = task.get(goal ? 'inputs' : 'outputs').findIndex(r => r.get(goal ? 'target' : 'source') === path);
  if (i < 0) return undefined;
  // A path that is not the message's is the path's fault; anything else, the value's.
  const part = /is not a (goal|result) field/.test(d.message) || !goal ? 'path' : 'expr';
  return `${el.id}-trace-${kind}s-${i}-${part}`;
}

/** Marks the selected element's problems on the panel fields they are in (the properties
 * panel's own error display). */
function markFields() {
  const [el] = modeler.get('selection').get();
  const errors = {};
  for (const d of el ? problems.of(el.id) : []) {
    const entry = d.field && entryOf(el, d);
    if (entry && !errors[entry]) errors[entry] = d.severity === 'error' ? d.message : `warning: ${d.message}`;
  }
  document.body.dataset.fieldErrors = JSON.stringify(errors);
  modeler.get('eventBus').fire('propertiesPanel.setErrors', { errors });
}
modeler.on('selection.changed', () => markFields());

modeler.on('commandStack.changed', () => {
  dirty = true;
  // A game of the model as it was is over.
  simulation.stop();
  clearTimeout(checking);
  checking = setTimeout(check, 400);
});

$('missions').addEventListener('change', e => {
  if (dirty && !confirm(`Leave ${current} without saving?`)) {
    e.target.value = current;
    return;
  }
  open(e.target.value).catch(err => say(err.message, 'bad'));
});
$('new').addEventListener('click', () => create().catch(err => say(err.message, 'bad')));
$('new-process').addEventListener('click', () => newProcess().catch(err => say(err.message, 'bad')));
$('zoom-in').addEventListener('click', () => modeler.get('zoomScroll').stepZoom(1));
$('zoom-out').addEventListener('click', () => modeler.get('zoomScroll').stepZoom(-1));
$('zoom-fit').addEventListener('click', () => fitView());
$('diagrams').addEventListener('change', e => openDiagram(e.target.value).catch(err => say(err.message, 'bad')));
// A call activity opens the process it calls, when the file draws it.
modeler.on('element.dblclick', 1500, ({ element }) => {
  const called = element.businessObject && element.businessObject.calledElement;
  if (!called) return;
  const d = (modeler.getDefinitions().diagrams || [])
    .find(x => x.plane && x.plane.bpmnElement && x.plane.bpmnElement.id === called);
  if (!d) return undefined;
  openDiagram(d.id).catch(err => say(err.message, 'bad'));
  return false; // not a label edit
});
$('save').addEventListener('click', () => save());
window.addEventListener('keydown', e => {
  if ((e.ctrlKey || e.metaKey) && e.key === 's') {
    e.preventDefault();
    save();
  }
});
window.addEventListener('beforeunload', e => { if (dirty) e.preventDefault(); });

// For tests and tools: the modeler, to read the model the page holds.
window.studio = { modeler, catalogue, errors, verification, simulation, ops, recording };

/**
 * Fetches the catalogues (the server asks the running systems first) and shows where each
 * came from; the model is checked again when that changed.
 */
async function catalogues() {
  const list = JSON.parse(await api('/api/catalogues'));
  catalogue.actions = list.flatMap(c => c.actions);
  const systems = list.map(c => `${c.server} (${c.source})`).join(' · ') || 'none';
  const changed = $('systems').textContent !== `catalogues: ${systems}`;
  $('systems').textContent = `catalogues: ${systems}`;
  document.body.dataset.systems = systems;
  if (changed && current) check();
}

// Systems come and go while a planner draws.
setInterval(() => catalogues().catch(e => say(`catalogues: ${e.message}`, 'bad')), 10000);

(async () => {
  try {
    await catalogues();
    const wanted = new URLSearchParams(location.search).get('file');
    const files = await listMissions();
    const first = wanted || (files[0] && files[0].name);
    if (first) await open(first); else await create(false);
  } catch (e) {
    say(e.message, 'bad');
  }
  document.body.dataset.ready = 'true';
})();
