// The differential test's page (tests/it/simulated.rs): bpmn-js-token-simulation's own
// simulator runs a model, driven at random from a seed, and returns what it did as a scenario of
// the token-simulation corpus's format (the steps and the trace) for `trace conformance
// token-simulation` to replay on the engine.
import Viewer from 'bpmn-js/lib/Viewer';
import SimulatorModule from 'bpmn-js-token-simulation/lib/simulator';

const DI = 'http://www.omg.org/spec/BPMN/20100524/DI';
const DC = 'http://www.omg.org/spec/DD/20100524/DC';
const DDI = 'http://www.omg.org/spec/DD/20100524/DI';

// The elements drawn as shapes: tasks, events, gateways, call activities.
const NODE = /(Task|^task|Event|Gateway|^callActivity)$/;

// A diagram for a model drawn without one: bpmn-js simulates only what it draws. Shapes sit on
// a grid; an edge runs from its source's centre to its target's. A sub-process is drawn
// collapsed, its content on a plane of its own, when `collapse()` says so (unless a message flow
// reaches inside it).
function withDiagram(xml, collapse) {
  const doc = new DOMParser().parseFromString(xml, 'application/xml');
  const broken = doc.getElementsByTagName('parsererror')[0];
  if (broken) {
    throw new Error(broken.textContent);
  }
  const root = doc.documentElement;
  const top = [...root.children];
  const collaboration = top.find(e => e.localName === 'collaboration');
  const processes = new Map(top.filter(e => e.localName === 'process').map(p => [ p.getAttribute('id'), p ]));
  const newPlane = of => {
    const diagram = doc.createElementNS(DI, 'bpmndi:BPMNDiagram');
    diagram.setAttribute('id', `Diagram_${of}`);
    const plane = doc.createElementNS(DI, 'bpmndi:BPMNPlane');
    plane.setAttribute('id', `Plane_${of}`);
    plane.setAttribute('bpmnElement', of);
    diagram.appendChild(plane);
    root.appendChild(diagram);
    return plane;
  };
  const planeOf = collaboration || [...processes.values()][0];
  const plane = newPlane(planeOf.getAttribute('id'));
  const centres = new Map();
  const edges = [];
  // What message flows connect stays on the collaboration's plane.
  const ends = new Set([ ...doc.getElementsByTagNameNS('*', 'messageFlow') ]
    .flatMap(m => [ m.getAttribute('sourceRef'), m.getAttribute('targetRef') ]));
  let count = 0;
  const shape = (plane, el, width, height, extra = {}) => {
    const id = el.getAttribute('id');
    const s = doc.createElementNS(DI, 'bpmndi:BPMNShape');
    s.setAttribute('id', `${id}_di`);
    s.setAttribute('bpmnElement', id);
    for (const [ k, v ] of Object.entries(extra)) {
      s.setAttribute(k, v);
    }
    const x = 100 + (count % 25) * 160;
    const y = 100 + Math.floor(count / 25) * 140;
    count += 1;
    const b = doc.createElementNS(DC, 'dc:Bounds');
    for (const [ k, v ] of Object.entries({ x, y, width, height })) {
      b.setAttribute(k, String(v));
    }
    s.appendChild(b);
    plane.appendChild(s);
    centres.set(id, { x: x + width / 2, y: y + height / 2 });
  };
  const walk = (container, plane) => {
    for (const el of container.children) {
      const name = el.localName;
      if (name === 'sequenceFlow' || name === 'association') {
        edges.push([ el, plane ]);
      } else if (name === 'subProcess' || name === 'transaction' || name === 'adHocSubProcess') {
        const messaged = [ ...el.querySelectorAll('*') ].some(c => ends.has(c.getAttribute('id')));
        if (collapse() && !messaged) {
          shape(plane, el, 100, 80, { isExpanded: 'false' });
          walk(el, newPlane(el.getAttribute('id')));
        } else {
          shape(plane, el, 350, 200, { isExpanded: 'true' });
          walk(el, plane);
        }
      } else if (NODE.test(name)) {
        shape(plane, el, 100, 80);
      }
    }
  };
  if (collaboration) {
    for (const el of collaboration.children) {
      if (el.localName === 'participant') {
        shape(plane, el, 4000, 600, { isHorizontal: 'true' });
        const p = processes.get(el.getAttribute('processRef'));
        if (p) {
          walk(p, plane);
        }
      } else if (el.localName === 'messageFlow') {
        edges.push([ el, plane ]);
      }
    }
  } else {
    walk(planeOf, plane);
  }
  for (const [ el, plane ] of edges) {
    const from = centres.get(el.getAttribute('sourceRef'));
    const to = centres.get(el.getAttribute('targetRef'));
    if (!from || !to) {
      continue;
    }
    const e = doc.createElementNS(DI, 'bpmndi:BPMNEdge');
    e.setAttribute('id', `${el.getAttribute('id')}_di`);
    e.setAttribute('bpmnElement', el.getAttribute('id'));
    for (const point of [ from, to ]) {
      const w = doc.createElementNS(DDI, 'di:waypoint');
      w.setAttribute('x', String(point.x));
      w.setAttribute('y', String(point.y));
      e.appendChild(w);
    }
    plane.appendChild(e);
  }
  return new XMLSerializer().serializeToString(doc);
}

// xorshift32: a reproducible stream from a seed.
function random(seed) {
  let x = (seed >>> 0) || 1;
  return n => {
    x ^= x << 13;
    x >>>= 0;
    x ^= x >>> 17;
    x ^= x << 5;
    x >>>= 0;
    return x % n;
  };
}

// Trace events per model, at most.
const MOVES = 20000;

const is = (el, type) => el.businessObject && el.businessObject.$instanceOf(type);

// What the outside may trigger, as a user of the simulator does (its context pad calls
// `trigger` with the element's subscription): a process's none start event (or, without one, an
// element without incoming flow), once per process; a timer, message or condition on a catch
// event, a boundary event or an event sub-process's start; a receive task; a task told to wait.
// Messages along a message flow, signals, errors, escalations, compensation and cancellation
// come only from the model itself.
function outside(subscription, started) {
  const { event, element } = subscription;
  if (!element || element.incoming.some(c => is(c, 'bpmn:MessageFlow'))) {
    return false;
  }
  if (event.type === 'continue') {
    return true;
  }
  if (!subscription.scope.parent) {
    // A process's start event, or an element without incoming flow of a process without one.
    return event.type === 'none' && !started.has(subscription.scope.element.id);
  }
  if (is(element, 'bpmn:ReceiveTask')) {
    return event.type === 'message';
  }
  return [ 'timer', 'message', 'condition' ].includes(event.type);
}

// Runs `xml` in the simulator: gateway choices and waiting tasks drawn from `seed`, then up to
// `limit` outside triggers. Returns `{ steps, trace, warnings }` or `{ error }`.
window.simulate = async function(xml, seed, limit) {
  const container = document.createElement('div');
  document.body.appendChild(container);
  const viewer = new Viewer({ container, additionalModules: [ SimulatorModule ] });
  try {
    const draw = random(seed);
    const { warnings } = await viewer.importXML(withDiagram(xml, () => draw(100) < 25));
    const simulator = viewer.get('simulator');
    const registry = viewer.get('elementRegistry');
    const steps = [];
    const trace = [];
    simulator.on('trace', e => {
      // A model the simulator loops on forever: given up, with the reason.
      if (trace.length >= MOVES) {
        throw new Error(`the simulator did not settle within ${MOVES} moves`);
      }
      trace.push(`${e.action}:${e.element.id}:${e.scope ? e.scope.id : null}`);
    });
    simulator.reset();
    for (const gateway of registry.filter(e => is(e, 'bpmn:ExclusiveGateway') || is(e, 'bpmn:InclusiveGateway'))) {
      const outgoing = gateway.outgoing.filter(c => is(c, 'bpmn:SequenceFlow'));
      if (outgoing.length < 2) {
        continue;
      }
      let chosen = [ outgoing[draw(outgoing.length)] ];
      if (is(gateway, 'bpmn:InclusiveGateway')) {
        const some = outgoing.filter(() => draw(2) === 0);
        chosen = some.length ? some : chosen;
      }
      steps.push({ op: 'setConfig', gateway: gateway.id, activeOutgoing: chosen.map(c => c.id) });
      simulator.setConfig(gateway, { activeOutgoing: is(gateway, 'bpmn:InclusiveGateway') ? chosen : chosen[0] });
    }
    for (const task of registry.filter(e => is(e, 'bpmn:Task') && !is(e, 'bpmn:ReceiveTask'))) {
      if (draw(100) < ((task.attachers || []).length ? 60 : 10)) {
        steps.push({ op: 'waitAtElement', element: task.id });
        simulator.waitAtElement(task);
      }
    }
    const started = new Set();
    for (let n = 0; n < limit; n++) {
      const open = simulator.findSubscriptions({}).filter(s => outside(s, started));
      // Only an element waiting in one place: a step names the element, not its scope.
      const once = open.filter(s => open.filter(o => o.element === s.element).length === 1);
      if (!once.length) {
        break;
      }
      once.sort((a, b) => (a.element.id < b.element.id ? -1 : a.element.id > b.element.id ? 1 : 0));
      const { event, scope, element } = once[draw(once.length)];
      const step = { op: 'trigger', element: element.id };
      if (is(element, 'bpmn:BoundaryEvent')) {
        step.scopeOf = element.host.id;
      }
      if (!scope.parent) {
        started.add(scope.element.id);
      }
      steps.push(step);
      simulator.trigger({ event, scope });
    }
    return { steps, trace, warnings: warnings.map(w => String(w.message || w)) };
  } catch (e) {
    return { error: String(e && e.stack || e) };
  } finally {
    viewer.destroy();
    container.remove();
  }
};
