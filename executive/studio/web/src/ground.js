// Ground decisions in the operations view: the studio is a ground station in the protocol's
// sense (`trace studio --station NAME`); each user task that opens is announced, and listed
// with its form, the context the mission shows (as labelled values and tables, not raw JSON)
// and its deadline, counted down in mission time; an operator (named, as at the terminal
// station) answers in typed fields checked before sending. The executive judges the answer like
// any station's. A task that closes is listed with who or what closed it (`answered by
// ana@web`, another station, the mission withdrawing it when its timer fired, …).

/** How long until a deadline, for people: `2 h 05 min`, `4 min 10 s`, `overdue by 12 s`. */
export function countdown(ms) {
  const late = ms < 0;
  const s = Math.floor(Math.abs(ms) / 1000);
  const d = Math.floor(s / 86400);
  const h = Math.floor((s % 86400) / 3600);
  const m = Math.floor((s % 3600) / 60);
  const pad = n => String(n).padStart(2, '0');
  let text;
  if (d) text = `${d} d ${h} h`;
  else if (h) text = `${h} h ${pad(m)} min`;
  else text = `${m} min ${pad(s % 60)} s`;
  return late ? `overdue by ${text}` : `${text} left`;
}

/** A value the mission shows, readable: a record as labelled values, a list of records as a
 * table, a list as a list; deeper than four levels, as JSON. */
export function readable(v, depth = 0) {
  const el = (tag, text) => {
    const e = document.createElement(tag);
    if (text !== undefined) e.textContent = text;
    return e;
  };
  const record = x => x !== null && typeof x === 'object' && !Array.isArray(x);
  if (v === null || v === undefined) return el('span', '—');
  if (typeof v !== 'object') return el('span', String(v));
  if (depth >= 4) return el('code', JSON.stringify(v));
  if (Array.isArray(v)) {
    if (!v.length) return el('span', '(none)');
    if (v.every(record)) {
      const keys = [...new Set(v.flatMap(Object.keys))];
      const table = el('table');
      const head = el('tr');
      head.append(...keys.map(k => el('th', k)));
      table.append(head);
      for (const row of v) {
        const tr = el('tr');
        for (const k of keys) {
          const td = el('td');
          td.append(readable(row[k], depth + 1));
          tr.append(td);
        }
        table.append(tr);
      }
      return table;
    }
    const ul = el('ul');
    for (const x of v) {
      const li = el('li');
      li.append(readable(x, depth + 1));
      ul.append(li);
    }
    return ul;
  }
  const dl = el('dl');
  for (const [k, x] of Object.entries(v)) {
    const dd = el('dd');
    dd.append(readable(x, depth + 1));
    dl.append(el('dt', k), dd);
  }
  if (!dl.children.length) return el('span', '(nothing)');
  return dl;
}

/** Reads one form field's text as its type; throws a message naming what is wrong. */
export function typed(name, type, text) {
  const optional = type.endsWith('?');
  const base = optional ? type.slice(0, -1) : type;
  if (text === '') {
    if (optional) return undefined;
    throw new Error(`${name} is required`);
  }
  switch (base) {
    case 'bool':
      if (text === 'true' || text === 'false') return text === 'true';
      throw new Error(`${name} must be true or false`);
    case 'int':
      if (/^-?\d+$/.test(text)) return Number(text);
      throw new Error(`${name} must be a whole number`);
    case 'f64':
      if (text.trim() !== '' && Number.isFinite(Number(text))) return Number(text);
      throw new Error(`${name} must be a number`);
    case 'string':
    case 'timestamp':
      return text;
    default:
      try { return JSON.parse(text); } catch (_) { throw new Error(`${name} must be JSON (${base})`); }
  }
}

/** Wires the ground section; `ctx` gives `api`, `say` and `now` (the followed mission's clock
 * in mission ms, or null while none is known). */
export function setupGround(ctx) {
  const { api, say, now } = ctx;
  const $ = id => document.getElementById(id);
  $('operator').value = localStorage.getItem('trace.operator') || '';
  $('operator').addEventListener('change', () => localStorage.setItem('trace.operator', $('operator').value));
  let shown = '';   // the task numbers shown, so typing is not wiped by a refresh
  const seen = new Set(); // the task numbers announced

  /** Counts every open task's deadline down, in mission time. */
  function tick() {
    const at = now();
    for (const c of document.querySelectorAll('#ground-tasks .countdown')) {
      const due = Number(c.dataset.deadline);
      if (at === null || !Number.isFinite(due)) {
        c.textContent = '';
        continue;
      }
      c.dataset.left = String(due - at);
      c.textContent = ` (${countdown(due - at)})`;
      c.classList.toggle('overdue', due < at);
    }
  }
  setInterval(tick, 1000);

  function form(t) {
    const box = document.createElement('div');
    box.className = 'ground-task';
    box.dataset.number = String(t.number);
    box.dataset.task = t.task;
    const head = document.createElement('strong');
    head.textContent = `${t.number}. ${t.name}${t.deadline ? ` — answer by ${t.deadline}` : ''}`;
    const left = document.createElement('span');
    left.className = 'countdown';
    if (Number.isFinite(t.deadline_ms)) left.dataset.deadline = String(t.deadline_ms);
    const context = document.createElement('div');
    context.className = 'context';
    context.append(readable(t.context));
    box.append(head, left, context);
    const fields = Object.entries((t.form && t.form.fields) || {});
    const inputs = {};
    for (const [name, type] of fields) {
      const label = document.createElement('label');
      const base = typeof type === 'string' ? type.replace(/\?$/, '') : 'json';
      let input;
      if (base === 'bool') {
        input = document.createElement('select');
        const choices = type.endsWith('?') ? ['', 'true', 'false'] : ['true', 'false'];
        input.replaceChildren(...choices.map(c => new Option(c || '(none)', c)));
      } else {
        input = document.createElement('input');
        input.size = 16;
      }
      input.name = name;
      input.dataset.type = typeof type === 'string' ? type : 'json';
      const error = document.createElement('span');
      error.className = 'field-error';
      label.append(`${name} (${typeof type === 'string' ? type : 'message'}) `, input, ' ', error);
      inputs[name] = { input, error };
      box.append(label);
    }
    const send = document.createElement('button');
    send.type = 'button';
    send.textContent = 'Answer';
    const result = document.createElement('span');
    send.addEventListener('click', async () => {
      const operator = $('operator').value.trim();
      const answer = {};
      let bad = false;
      for (const [name, { input, error }] of Object.entries(inputs)) {
        error.textContent = '';
        try {
          const v = typed(name, input.dataset.type, input.value);
          if (v !== undefined) answer[name] = v;
        } catch (e) {
          error.textContent = e.message;
          bad = true;
        }
      }
      if (!operator) {
        result.className = 'answer-error';
        result.textContent = ' who answers? (operator)';
        bad = true;
      }
      if (bad) return;
      result.className = '';
      result.textContent = ' sent, waiting for the executive…';
      try {
        const r = JSON.parse(await api(`/api/ground/${t.number}`, {
          method: 'POST', headers: { 'Content-Type': 'application/json' },
          body: JSON.stringify({ operator, fields: answer }),
        }));
        result.className = r.applied ? 'answer-ok' : 'answer-error';
        result.textContent = ` ${r.said[r.said.length - 1] || (r.applied ? 'applied' : 'not applied')}`;
        box.dataset.outcome = r.applied ? 'applied' : 'refused';
      } catch (e) {
        result.className = 'answer-error';
        result.textContent = ` ${e.message}`;
        box.dataset.outcome = 'error';
      }
    });
    box.append(send, result);
    return box;
  }

  async function refresh() {
    let desk;
    try {
      desk = JSON.parse(await api('/api/ground'));
    } catch (_) {
      $('ground').hidden = true;   // not a ground station
      return;
    }
    $('ground').hidden = false;
    $('ground-station').textContent = `(station ${desk.station})`;
    const numbers = desk.tasks.map(t => t.number).join(',');
    if (numbers !== shown) {
      // Answered forms stay until the next change, so their outcome can be read.
      const kept = [...$('ground-tasks').children].filter(b => b.dataset.outcome);
      $('ground-tasks').replaceChildren(...kept, ...desk.tasks.map(form));
      shown = numbers;
      tick();
    }
    // Each task that opens is announced once.
    const fresh = desk.tasks.filter(t => !seen.has(t.number));
    for (const t of fresh) {
      seen.add(t.number);
      const text = `Ground decision ${t.number} open: ${t.name}${t.deadline ? `, answer by ${t.deadline}` : ''}`;
      $('ground-announce').textContent = text;
      say(text, 'warn');
    }
    document.title = desk.tasks.length ? `(${desk.tasks.length}) TRACE Studio` : 'TRACE Studio';
    $('ground-closed').replaceChildren(...desk.closed.slice().reverse().map(c => {
      const li = document.createElement('li');
      li.dataset.number = String(c.number);
      li.dataset.task = c.task;
      li.dataset.closed = c.why;
      li.textContent = `${c.number}. ${c.name}: ${c.why}`;
      return li;
    }));
    $('ground-log').replaceChildren(...desk.log.slice(-10).map(l => {
      const li = document.createElement('li');
      li.textContent = l;
      return li;
    }));
    document.body.dataset.groundTasks = numbers;
  }

  return { refresh };
}
