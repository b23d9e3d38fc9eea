// Ground decisions in the operations view: the studio is a ground station in the protocol's
// sense (`trace studio --station NAME`); its open user tasks are listed with their form, the
// context the mission shows and the deadline, and an operator (named, as at the terminal
// station) answers in typed fields checked before sending. The executive judges the answer like
// any station's; the station's event lines say who answered each task (another station first,
// the mission's own timer, …).

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

/** Wires the ground section; `ctx` gives `api`. */
export function setupGround(ctx) {
  const { api } = ctx;
  const $ = id => document.getElementById(id);
  $('operator').value = localStorage.getItem('trace.operator') || '';
  $('operator').addEventListener('change', () => localStorage.setItem('trace.operator', $('operator').value));
  let shown = '';   // the task numbers shown, so typing is not wiped by a refresh

  function form(t) {
    const box = document.createElement('div');
    box.className = 'ground-task';
    box.dataset.number = String(t.number);
    box.dataset.task = t.task;
    const head = document.createElement('strong');
    head.textContent = `${t.number}. ${t.name}${t.deadline ? ` — until ${t.deadline}` : ''}`;
    const context = document.createElement('pre');
    context.textContent = JSON.stringify(t.context, null, 1);
    box.append(head, context);
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
    }
    $('ground-log').replaceChildren(...desk.log.slice(-10).map(l => {
      const li = document.createElement('li');
      li.textContent = l;
      return li;
    }));
    document.body.dataset.groundTasks = numbers;
  }

  return { refresh };
}
