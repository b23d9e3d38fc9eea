// The token game on the diagram: the model as drawn is played by the executive's own engine
// (token-game mode, on the server: `executive_studio::simulate`), not by a JavaScript copy of
// BPMN. The page shows where the tokens are (a count on each element), and offers what the
// player may do next: complete or fail a waiting task (with the codes its error boundaries
// catch), choose a gateway's flow, fire a timer, message, signal or boundary.

import { showTokens } from './tokens.js';

/** Wires the simulation box; `ctx` gives the modeler, `api` and `say`. */
export function setupSimulate(ctx) {
  const { modeler, api, say } = ctx;
  const $ = id => document.getElementById(id);
  let game = null;   // the server's id of the game being played
  let view = null;   // its last view

  function clear() {
    const canvas = modeler.get('canvas');
    for (const el of modeler.get('elementRegistry').getAll()) canvas.removeMarker(el, 'trace-live');
    modeler.get('overlays').remove({ type: 'trace-sim' });
  }

  const nameOf = id => {
    const el = modeler.get('elementRegistry').get(id);
    const bo = el && el.businessObject;
    return (bo && bo.name) || id;
  };

  /** What a flow leads to, for its button. */
  const flowLabel = id => {
    const el = modeler.get('elementRegistry').get(id);
    const bo = el && el.businessObject;
    if (!bo) return id;
    return bo.name ? `${bo.name} → ${nameOf(bo.targetRef.id)}` : `→ ${nameOf(bo.targetRef.id)}`;
  };

  function button(label, act, data) {
    const b = document.createElement('button');
    b.type = 'button';
    b.textContent = label;
    Object.assign(b.dataset, data);
    b.addEventListener('click', () => play(act));
    const li = document.createElement('li');
    li.append(b);
    return li;
  }

  function render() {
    clear();
    showTokens(modeler, Object.fromEntries(view.tokens.map(t => [t.element, t.count])), 'trace-sim');
    const acts = [];
    for (const t of view.tasks) {
      acts.push(button(`Complete ${t.name}`, { act: 'complete', element: t.element },
        { act: 'complete', element: t.element }));
      for (const code of t.catches) {
        const c = code === '*' ? 'ERROR' : code;
        acts.push(button(`Fail ${t.name} with ${c}`, { act: 'fail', element: t.element, code: c },
          { act: 'fail', element: t.element, code: c }));
      }
    }
    for (const g of view.gateways) {
      for (const f of g.flows) {
        acts.push(button(`${nameOf(g.element)}: take ${flowLabel(f)}`,
          { act: 'choose', gateway: g.element, flows: [f] },
          { act: 'choose', element: g.element, flow: f }));
      }
    }
    for (const w of view.waits) {
      acts.push(button(`Fire ${w.kind} ${w.label}`, { act: 'fire', element: w.element },
        { act: 'fire', element: w.element }));
    }
    $('simulate-acts').replaceChildren(...acts);
    $('simulate-trace').replaceChildren(...view.trace.slice(-12).map(e => {
      const li = document.createElement('li');
      li.textContent = e;
      return li;
    }));
    const state = view.ended ? `ended: ${view.outcome}` : `playing, ${view.steps} steps`;
    $('simulate-status').textContent = state + (view.incidents.length ? ` — ${view.incidents.join('; ')}` : '');
    document.body.dataset.simulation = view.ended ? `ended:${view.outcome}` : 'playing';
    // Each view shown, counted: a tool waits for the next one after an act.
    document.body.dataset.simulationViews = String(Number(document.body.dataset.simulationViews || 0) + 1);
  }

  async function play(act) {
    try {
      const r = JSON.parse(await api(`/api/simulate/${game}`, {
        method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(act),
      }));
      view = r.view;
    } catch (e) {
      say(`simulation: ${e.message}`, 'bad');
    }
    render();
  }

  async function start() {
    const { xml } = await modeler.saveXML();
    if (game) api(`/api/simulate/${game}`, { method: 'DELETE' }).catch(() => {});
    try {
      const r = JSON.parse(await api('/api/simulate', {
        method: 'POST', headers: { 'Content-Type': 'application/xml' }, body: xml,
      }));
      game = r.id;
      view = r.view;
      $('simulate').textContent = 'Restart';
      render();
    } catch (e) {
      $('simulate-status').textContent = `cannot play: ${e.message}`;
      document.body.dataset.simulation = 'refused';
    }
  }

  /** Stops showing the game (the model changed or another file opened). */
  function stop() {
    if (game) api(`/api/simulate/${game}`, { method: 'DELETE' }).catch(() => {});
    game = null;
    view = null;
    clear();
    $('simulate').textContent = 'Start';
    $('simulate-acts').replaceChildren();
    $('simulate-trace').replaceChildren();
    $('simulate-status').textContent = '';
    document.body.dataset.simulation = '';
  }

  /** Draws the game again (another diagram of the file shown). */
  function redraw() {
    if (view) render();
  }

  $('simulate').addEventListener('click', () => start());
  return { start, stop, redraw, view: () => view };
}
