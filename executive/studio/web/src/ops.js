// The operations view: a running mission followed live on its own diagram. The studio's server
// follows the executive over Zenoh as `trace monitor` does and passes on, as server-sent
// events, its present state (first, and again after each burst of record lines) and every
// record line; this page draws them: tokens with their counts (the state's, so always the
// engine's own), activities in flight with their last feedback and how long they have run,
// elements completed, failed tasks and incidents, timers with their deadlines in mission time,
// the variables decisions read, and a plain line when the executive goes or comes back — or,
// when its mission has ended, that it ended and how (its timeline stays, drawn from what the
// studio kept of its record). The
// executives of a fleet (`trace run --participant`: one per pool of a collaboration, each
// running the same model) are followed together: each pool's tokens on the one diagram, and
// every message flow a message has crossed marked.
import NavigatedViewer from 'bpmn-js/lib/NavigatedViewer';
import { setupGround } from './ground.js';
import { showTokens } from './tokens.js';

const fmt = ms => (Number.isFinite(ms) ? new Date(ms).toISOString().replace('.000Z', 'Z') : '?');

/** How long, for people: `3 h 12 min`. */
function span(ms) {
  if (!Number.isFinite(ms) || ms < 0) return '';
  const min = Math.round(ms / 60000);
  if (min < 60) return `${min} min`;
  const h = Math.floor(min / 60);
  return h < 48 ? `${h} h ${min % 60} min` : `${Math.floor(h / 24)} d ${h % 24} h`;
}

/** Wires the operations view; `ctx` gives `api` and `say`. */
export function setupOps(ctx) {
  const { api, say } = ctx;
  const $ = id => document.getElementById(id);
  const viewer = new NavigatedViewer({ container: '#ops-canvas' });
  let undrawn = '';      // why the chosen mission's model is not drawn, if it is not
  let clock = null;      // the chosen executive's mission clock: {now_ms, speed, wall}
  /** Mission time now on the chosen executive's clock, or null while none is known. */
  const missionNow = () => (clock ? clock.now_ms + (Date.now() - clock.wall) * clock.speed : null);
  const ground = setupGround({ api, say, now: missionNow });
  let sources = {};      // mission → the EventSource following it
  let mission = null;    // the mission chosen
  let model = null;      // its model's XML: another executive running it is of the same fleet
  const others = new Set(); // missions seen running another model
  let states = {};       // mission → its last state
  let state = null;      // the states merged: the fleet's tokens, flights, timers, flows
  const crossed = new Set(); // message flows crossed, from the record lines seen
  let lines = [];        // record lines since the page joined
  const dispatched = {}; // task key → {element, name, resource, at}
  const feedback = {};   // task key → last feedback line
  const done = new Set();
  const failed = new Set();
  const outcomes = {};   // instance → its outcome, null while it runs (state and record)
  let endedAt = NaN;     // mission time of the last instance_finished line

  /** The outcomes of the chosen mission's instances once every one has ended, else null. */
  function ending() {
    const all = Object.values(outcomes);
    return all.length && all.every(o => o) ? all : null;
  }

  /** The fleet's state: every executive's tokens, flights and timers, the chosen one's rest. */
  function merged() {
    const all = Object.values(states);
    if (!all.length) return null;
    const tokens = {};
    for (const s of all) for (const [k, n] of Object.entries(s.tokens || {})) tokens[k] = (tokens[k] || 0) + n;
    const base = states[mission] || all[0];
    for (const s of all) for (const f of (s.fleet && s.fleet.flows) || []) crossed.add(f);
    return {
      ...base,
      tokens,
      in_flight: all.flatMap(s => s.in_flight || []),
      timers: all.flatMap(s => s.timers || []),
      decision_vars: Object.assign({}, ...all.map(s => s.decision_vars || {})),
      instances: all.flatMap(s => s.instances || []),
      mission_ms: Math.max(...all.map(s => s.mission_ms || 0)),
      pools: all.filter(s => s.fleet).map(s => s.fleet.pool).sort(),
    };
  }

  function mark() {
    state = merged();
    if (!state) return;
    const canvas = viewer.get('canvas');
    const overlays = viewer.get('overlays');
    const registry = viewer.get('elementRegistry');
    overlays.remove({ type: 'ops' });
    for (const el of registry.getAll()) {
      for (const m of ['trace-live', 'ops-done', 'ops-flight', 'ops-failed', 'ops-message']) canvas.removeMarker(el, m);
    }
    for (const f of crossed) if (registry.get(f)) canvas.addMarker(f, 'ops-message');
    for (const id of done) if (registry.get(id)) canvas.addMarker(id, 'ops-done');
    for (const id of failed) if (registry.get(id)) canvas.addMarker(id, 'ops-failed');
    const flights = state.in_flight || [];
    for (const f of flights) if (registry.get(f.element)) canvas.addMarker(f.element, 'ops-flight');
    showTokens(viewer, state.tokens || {}, 'ops');
    const now = state.mission_ms;
    $('ops-flight').replaceChildren(...flights.map(f => {
      const li = document.createElement('li');
      const fb = feedback[f.task] || (f.feedback && { progress_pct: f.feedback.progress_pct });
      const progress = fb && Number.isFinite(fb.progress_pct) ? ` ${Math.round(fb.progress_pct)} %` : '';
      const since = dispatched[f.task] ? `, for ${span(now - dispatched[f.task].at)}` : '';
      li.textContent = f.user_task
        ? `${f.name}: waits for the ground${f.deadline_ms ? ` until ${fmt(f.deadline_ms)}` : ''}${since}`
        : `${f.name} (${f.resource})${progress}${since}`;
      li.dataset.element = f.element;
      return li;
    }));
    $('ops-timers').replaceChildren(...(state.timers || []).map(t => {
      const li = document.createElement('li');
      li.textContent = `${t.element}: at ${fmt(t.due_ms)} (in ${span(t.due_ms - now)})`;
      return li;
    }));
    $('ops-vars').replaceChildren(...Object.entries(state.decision_vars || {}).map(([k, v]) => {
      const li = document.createElement('li');
      li.textContent = `${k} = ${JSON.stringify(v)}`;
      return li;
    }));
    const ended = Object.values(outcomes).filter(Boolean);
    document.body.dataset.opsSeq = String(state.seq);
    if (state.reboots) document.body.dataset.opsReboots = String(state.reboots);
    // Once the mission has ended and its executive left, the status says so and stays.
    if (!document.body.dataset.opsEnded) {
      $('ops-status').className = '';
      const fleet = state.pools.length > 1 ? `fleet: ${state.pools.join(', ')} · ` : '';
      $('ops-status').textContent = `${fleet}${mission} · step ${state.seq} · mission time ${fmt(now)}`
        + (ended.length ? ` · ended: ${ended.map(o => o.type || JSON.stringify(o)).join(', ')}` : '')
        + (state.reboots ? ` · resumed ${state.reboots} time${state.reboots === 1 ? '' : 's'}` : '')
        + undrawn;
    }
    document.body.dataset.opsFleet = state.pools.join(' ');
    document.body.dataset.opsMessageFlows = [...crossed].sort().join(' ');
    document.body.dataset.opsTokens = JSON.stringify(state.tokens || {});
  }

  // The timeline below the diagram, drawn by the server from the executive's record; drawn
  // again (at most every 3 s) while lines arrive, keeping the element selected.
  let selected = null;
  let stale = false;
  let drawing = null;
  let loads = 0;         // timeline pages asked for: each a new address, so each is loaded
  function timeline(now) {
    stale = true;
    if (drawing && !now) return;
    clearTimeout(drawing);
    drawing = setTimeout(() => {
      drawing = null;
      if (!stale || !mission) return;
      stale = false;
      loads += 1;
      $('ops-timeline').src = `/api/ops/${encodeURIComponent(mission)}/timeline?at=${lines.length}&n=${loads}`;
    }, now ? 0 : 3000);
  }
  $('ops-timeline').addEventListener('load', () => {
    const doc = $('ops-timeline').contentDocument;
    document.body.dataset.opsTimelineBars = doc && doc.body ? (doc.body.dataset.rendered || '0') : '0';
    if (selected) $('ops-timeline').contentWindow.postMessage({ trace: 'highlight', element: selected }, '*');
  });
  function select(id) {
    const canvas = viewer.get('canvas');
    const registry = viewer.get('elementRegistry');
    if (selected && registry.get(selected)) canvas.removeMarker(selected, 'ops-selected');
    selected = id;
    if (id && registry.get(id)) {
      canvas.addMarker(id, 'ops-selected');
      canvas.scrollToElement(registry.get(id));
    }
    document.body.dataset.opsSelected = id || '';
  }
  // A bar clicked in the timeline selects its element on the diagram…
  window.addEventListener('message', e => {
    if (e.source !== $('ops-timeline').contentWindow || !e.data || e.data.trace !== 'select') return;
    select(e.data.element);
  });
  // …and an element clicked on the diagram outlines its bars.
  viewer.on('element.click', e => {
    const id = e.element && e.element.businessObject && e.element.id;
    select(id);
    $('ops-timeline').contentWindow.postMessage({ trace: 'highlight', element: id }, '*');
  });

  /** A record line of the chosen executive (`own`), or of another of its fleet. */
  function line(v, own) {
    if (own) {
      lines.push(v);
      if (v.seq !== undefined || v.kind === 'reboot') timeline(false);
    }
    const id = v.element && v.element.id;
    switch (v.kind) {
      case 'instance_started':
        if (own && !(v.instance in outcomes)) outcomes[v.instance] = null;
        break;
      case 'instance_finished':
        if (own) {
          outcomes[v.instance] = v.outcome || { type: 'ended' };
          endedAt = v.mission_ms;
          // The end told after the going: said as an end.
          if (document.body.dataset.opsGone === 'true') left(mission);
        }
        break;
      case 'dispatched':
      case 'user_task_opened':
        dispatched[v.task] = { element: id, at: v.mission_ms };
        break;
      case 'left':
        if (id) done.add(id);
        break;
      case 'feedback':
        feedback[v.task] = v;
        break;
      case 'failed':
        if (dispatched[v.task]) failed.add(dispatched[v.task].element);
        break;
      case 'incident':
        if (id) failed.add(id);
        break;
      case 'reboot':
        if (own) document.body.dataset.opsReboots = String(v.reboots);
        break;
      case 'message_sent':
        if (v.flow) crossed.add(v.flow);
        break;
      default:
    }
    const li = document.createElement('li');
    li.textContent = `${v.kind} ${id || v.task || ''}${v.code ? ` ${v.code}` : ''}${v.kind === 'reboot' ? ' — the executive restarted' : ''}`;
    if (v.kind === 'reboot') li.className = 'reboot';
    $('ops-log').append(li);
    while ($('ops-log').children.length > 200) $('ops-log').firstChild.remove();
    document.body.dataset.opsLines = String(lines.length);
  }

  /** The chosen executive `m` has left: its mission ended (said so, the timeline drawn
   * complete), or it stopped or crashed. */
  function left(m) {
    const ended = ending();
    if (!ended) {
      document.body.dataset.opsGone = 'true';
      $('ops-status').className = 'gone';
      $('ops-status').textContent = `${m}: the executive is gone (stopped or crashed); waiting for it to come back`;
      return;
    }
    const how = [...new Set(ended.map(o => o.type || 'ended'))].join(', ');
    document.body.dataset.opsGone = '';
    document.body.dataset.opsEnded = how;
    $('ops-status').className = 'ended';
    const at = Number.isFinite(endedAt) ? endedAt : state && state.mission_ms;
    $('ops-status').textContent = `${m}: the mission ended (${how}) at mission time ${fmt(at)}; its executive has left`;
    timeline(true);
  }

  /** Follows executive `m`'s state and record (`own`: the one chosen). */
  function listen(m, own) {
    const source = new EventSource(`/api/ops/${encodeURIComponent(m)}/events`);
    sources[m] = source;
    source.addEventListener('state', e => {
      states[m] = JSON.parse(e.data);
      if (own) {
        document.body.dataset.opsGone = '';
        const c = states[m].clock;
        if (c && Number.isFinite(c.now_ms)) clock = { now_ms: c.now_ms, speed: c.speed || 0, wall: Date.now() };
        // A stale state never undoes an end the record told.
        for (const i of states[m].instances || []) outcomes[i.instance] = i.outcome || outcomes[i.instance] || null;
      }
      mark();
    });
    source.addEventListener('record', e => { line(JSON.parse(e.data), own); mark(); });
    if (!own) {
      source.addEventListener('gone', () => say(`${m}: an executive of the fleet is gone`, 'warn'));
      return;
    }
    source.addEventListener('gone', () => left(m));
    source.addEventListener('back', () => {
      document.body.dataset.opsEnded = '';
      document.body.dataset.opsBack = String(Number(document.body.dataset.opsBack || 0) + 1);
      say(`${m}: the executive is back`, 'ok');
    });
  }

  /** The other executives running the chosen one's model: the rest of its fleet, followed too. */
  async function fleet(list) {
    if (!model) return;
    for (const p of list) {
      if (!p.alive || p.mission === mission || sources[p.mission] || others.has(p.mission)) continue;
      let xml;
      try {
        xml = await api(`/api/ops/${encodeURIComponent(p.mission)}/model`);
      } catch (e) {
        continue;
      }
      if (xml === model) listen(p.mission, false);
      else others.add(p.mission);
    }
  }

  async function follow(id) {
    for (const s of Object.values(sources)) s.close();
    sources = {};
    states = {};
    others.clear();
    crossed.clear();
    mission = id;
    model = null;
    state = null;
    lines = [];
    done.clear();
    failed.clear();
    clock = null;
    endedAt = NaN;
    for (const k of Object.keys(outcomes)) delete outcomes[k];
    document.body.dataset.opsEnded = '';
    $('ops-log').replaceChildren();
    undrawn = '';
    try {
      model = await api(`/api/ops/${encodeURIComponent(id)}/model`);
    } catch (e) {
      $('ops-status').textContent = `${id}: cannot follow it — ${e.message}`;
      return;
    }
    // A model without a drawing (or one bpmn-js cannot draw) is followed all the same.
    try {
      await viewer.importXML(model);
      viewer.get('canvas').zoom('fit-viewport');
    } catch (e) {
      await viewer.clear();
      undrawn = ` · its model has no diagram to draw (${e.message})`;
    }
    listen(id, true);
    timeline(true);
  }

  async function executives() {
    const list = JSON.parse(await api('/api/ops/executives'));
    const box = $('executives');
    const chosen = box.value;
    box.replaceChildren(...list.map(p => new Option(`${p.mission}${p.alive ? '' : ' (gone)'}`, p.mission)));
    if (chosen) box.value = chosen;
    document.body.dataset.executives = list.map(p => p.mission).join(' ');
    if (!mission && list.some(p => p.alive)) await follow(list.find(p => p.alive).mission);
    await fleet(list);
  }

  let polling = null;
  function show(on) {
    document.body.classList.toggle('ops-mode', on);
    $('ops-canvas').hidden = !on;
    $('ops-timeline').hidden = !on;
    $('ops-side').hidden = !on;
    $('ops-toggle').textContent = on ? 'Compose' : 'Operations';
    clearInterval(polling);
    if (on) {
      const poll = () => {
        executives().catch(e => { $('ops-status').textContent = e.message; });
        ground.refresh();
      };
      poll();
      polling = setInterval(poll, 2000);
    }
  }

  $('ops-toggle').addEventListener('click', () => show(!document.body.classList.contains('ops-mode')));
  $('executives').addEventListener('change', e => follow(e.target.value));
  return { show, follow, select, state: () => state, lines: () => lines, viewer };
}
