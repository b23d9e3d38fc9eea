// Replay of an execution record on the open mission: the server replays it through the engine
// (`executive::replay`: every step read back into its input, the engine's lines checked
// against the record's), and the page scrubs through the engine's state after each step —
// tokens on the diagram, the step's input and mission time, instances ended by then.

import { showTokens } from './tokens.js';

/** Wires the record replay; `ctx` gives the modeler, `api` and `say`. */
export function setupRecord(ctx) {
  const { modeler, api, say } = ctx;
  const $ = id => document.getElementById(id);
  let frames = [];

  function clear() {
    const canvas = modeler.get('canvas');
    for (const el of modeler.get('elementRegistry').getAll()) canvas.removeMarker(el, 'trace-live');
    modeler.get('overlays').remove({ type: 'trace-record' });
  }

  function show(i) {
    clear();
    const f = frames[i];
    if (!f) return;
    showTokens(modeler, f.tokens, 'trace-record');
    const ended = Object.entries(f.ended).map(([i, o]) => `instance ${i} ${o}`).join(', ');
    $('record-frame').textContent = `step ${f.seq} (${i + 1} of ${frames.length}) · `
      + `${new Date(f.mission_ms).toISOString()} · ${f.what}${ended ? ` · ${ended}` : ''}`;
    document.body.dataset.recordSeq = String(f.seq);
    document.body.dataset.recordTokens = JSON.stringify(f.tokens);
  }

  async function load(file) {
    const record = await file.text();
    const { xml } = await modeler.saveXML();
    try {
      const r = JSON.parse(await api('/api/replay', {
        method: 'POST', headers: { 'Content-Type': 'application/json' },
        body: JSON.stringify({ model: xml, record }),
      }));
      frames = r.frames;
    } catch (e) {
      frames = [];
      $('record-replay').hidden = true;
      say(`${file.name}: not replayed — ${e.message}`, 'bad');
      document.body.dataset.recordFrames = 'refused';
      return;
    }
    $('record-replay').hidden = !frames.length;
    $('record-slider').max = String(Math.max(frames.length - 1, 0));
    $('record-slider').value = '0';
    say(`${file.name}: ${frames.length} steps replayed through the engine`, 'ok');
    document.body.dataset.recordFrames = String(frames.length);
    show(0);
  }

  /** Shows the state after step `seq` (the nearest step at or before it). */
  function at(seq) {
    let i = 0;
    while (i + 1 < frames.length && frames[i + 1].seq <= seq) i += 1;
    $('record-slider').value = String(i);
    show(i);
  }

  $('record-file').addEventListener('change', e => {
    const file = e.target.files && e.target.files[0];
    if (file) load(file);
  });
  $('record-slider').addEventListener('input', e => show(Number(e.target.value)));
  return { at, frames: () => frames, clear };
}
