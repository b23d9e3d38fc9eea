// Verification on the diagram: the mission's requirements edited beside it, `trace verify`
// run by the server on the model as the page holds it, every property's verdict listed, and a
// violated property's counterexample replayed on the diagram step by step (the visited
// elements shaded, the current one marked with its token, forward and back) — the same story
// `trace verify` prints.

/** Wires the verification box; `ctx` gives the modeler, `api`, `say` and the open file. */
export function setupVerify(ctx) {
  const { modeler, api, say } = ctx;
  const $ = id => document.getElementById(id);
  let steps = [];   // the counterexample being replayed
  let at = -1;      // its current step

  /** The diagram element a counterexample step shows on: inside a called process, the call. */
  function shown(step) {
    if (!step.step) return null;
    const registry = modeler.get('elementRegistry');
    const outer = step.step.path ? step.step.path.split('/')[0] : '';
    return registry.get(outer) || registry.get(step.step.element) || null;
  }

  function clear() {
    const canvas = modeler.get('canvas');
    for (const el of modeler.get('elementRegistry').getAll()) {
      canvas.removeMarker(el, 'trace-visited');
      canvas.removeMarker(el, 'trace-current');
    }
    modeler.get('overlays').remove({ type: 'trace-replay' });
  }

  function render() {
    clear();
    const canvas = modeler.get('canvas');
    const items = $('replay-steps').children;
    for (let i = 0; i < steps.length; i++) {
      if (items[i]) items[i].className = i === at ? 'current' : '';
      const el = i <= at ? shown(steps[i]) : null;
      if (el) canvas.addMarker(el, i === at ? 'trace-current' : 'trace-visited');
    }
    const step = steps[at];
    const el = step && shown(step);
    if (el) {
      const token = document.createElement('div');
      token.className = 'trace-token';
      token.textContent = String(at + 1);
      modeler.get('overlays').add(el, 'trace-replay', { position: { bottom: 0, left: -9 }, html: token });
      canvas.scrollToElement(el);
    }
    $('replay-step').textContent = step
      ? `step ${at + 1} of ${steps.length}: ${step.marker}${step.cycle_start ? ' (the cycle starts here)' : ''}`
      : '';
    document.body.dataset.replay = step ? `${at + 1}/${steps.length}:${el ? el.id : ''}` : '';
  }

  function replay(outcome) {
    steps = outcome.counterexample || [];
    at = steps.length ? 0 : -1;
    $('replay').hidden = !steps.length;
    $('replay-steps').replaceChildren(...steps.map((s, i) => {
      const li = document.createElement('li');
      li.textContent = s.marker;
      li.addEventListener('click', () => { at = i; render(); });
      return li;
    }));
    render();
  }

  async function loadRequirements(name) {
    let text = '';
    try {
      text = await api(`/api/requirements/${encodeURIComponent(name)}`);
    } catch (_) { /* none yet */ }
    $('requirements').value = text;
    $('properties').replaceChildren();
    $('verify-status').textContent = '';
    document.body.dataset.verified = '';
    steps = [];
    at = -1;
    $('replay').hidden = true;
    clear();
  }

  async function verify() {
    const name = ctx.current();
    if (!name) return;
    const { xml } = await modeler.saveXML();
    $('verify-status').textContent = 'verifying…';
    document.body.dataset.verified = '';
    let report;
    try {
      report = JSON.parse(await api(`/api/verify/${encodeURIComponent(name)}`, {
        method: 'POST',
        headers: { 'Content-Type': 'application/json' },
        body: JSON.stringify({ model: xml, requirements: $('requirements').value, native: true }),
      }));
    } catch (e) {
      $('verify-status').textContent = `not verified: ${e.message}`;
      document.body.dataset.verified = 'error';
      return;
    }
    const violated = report.properties.filter(p => p.verdict === 'violated');
    $('verify-status').textContent = violated.length
      ? `${violated.length} of ${report.properties.length} violated`
      : `${report.properties.length} properties hold`;
    $('properties').replaceChildren(...report.properties.map(p => {
      const li = document.createElement('li');
      li.className = `property ${p.verdict}`;
      li.dataset.name = p.name;
      li.textContent = `${p.verdict} ${p.name} — ${p.description}${p.why ? ` (${p.why})` : ''}${p.detail ? `: ${p.detail}` : ''}`;
      if (p.counterexample && p.counterexample.length) {
        li.title = 'Replay the counterexample on the diagram';
        li.addEventListener('click', () => replay(p));
      }
      return li;
    }));
    if (report.native) {
      // The engine's own exploration beside Spin's verdicts (`trace verify --native`).
      const n = report.native;
      const li = document.createElement('li');
      li.className = 'native';
      const found = [n.deadlock && 'a run that gets stuck', n.unsafe_run && 'an unsafe run',
        n.dead_activities.length && `never started: ${n.dead_activities.join(', ')}`,
        n.needs_data && `needs data: ${n.needs_data}`].filter(Boolean);
      li.textContent = `engine exploration: ${n.states} states${n.complete ? '' : ' (bounded)'}; `
        + (found.length ? found.join('; ') : 'no stuck or unsafe run, every activity started');
      $('properties').append(li);
    }
    document.body.dataset.verified = violated.length ? 'violated' : 'holds';
    if (violated.length) replay(violated[0]);
  }

  async function saveRequirements() {
    const name = ctx.current();
    if (!name) return;
    try {
      await api(`/api/requirements/${encodeURIComponent(name)}`, {
        method: 'PUT', headers: { 'Content-Type': 'text/plain' }, body: $('requirements').value,
      });
      say(`${name}: requirements saved`, 'ok');
    } catch (e) {
      say(`requirements not saved — ${e.message}`, 'bad');
    }
  }

  $('verify').addEventListener('click', () => verify());
  $('save-requirements').addEventListener('click', () => saveRequirements());
  $('replay-back').addEventListener('click', () => { if (at > 0) { at -= 1; render(); } });
  $('replay-forward').addEventListener('click', () => { if (at < steps.length - 1) { at += 1; render(); } });
  return { loadRequirements, verify, replay: () => ({ steps, at }) };
}
