// What a planner draws besides tasks, without XML: a sequence flow's condition, a call
// activity's called process (the file's processes and those of the files it imports), a script task's CEL script, a
// multi-instance activity's items (Camunda 8's `zeebe:loopCharacteristics`), and under a
// timer's value what it means (its first firings in mission time, or the executive's reason
// for refusing it, from `POST /api/timer`); and for every element, the problems the last check
// found on it, as the problem list says them. Each is written where the executive reads it and
// checked by the same check as `trace validate` once written (app.js marks the problems).
import { is, getBusinessObject } from 'bpmn-js/lib/util/ModelUtil';
import {
  SelectEntry, TextAreaEntry, TextFieldEntry, isSelectEntryEdited, isTextFieldEntryEdited,
  isTextAreaEntryEdited,
} from '@bpmn-io/properties-panel';
import { useService } from 'bpmn-js-properties-panel';
import { useEffect, useState } from '@bpmn-io/properties-panel/preact/hooks';
import { withExtension } from './provider.jsx';

/** Whether a flow's condition means something: out of a gateway that chooses, or an activity. */
function conditional(element) {
  if (!is(element, 'bpmn:SequenceFlow')) return false;
  const source = element.businessObject.sourceRef;
  return is(source, 'bpmn:ExclusiveGateway') || is(source, 'bpmn:InclusiveGateway')
    || is(source, 'bpmn:ComplexGateway') || is(source, 'bpmn:Activity');
}

function ConditionEntry({ element, id }) {
  const modeling = useService('modeling');
  const bpmnFactory = useService('bpmnFactory');
  const bo = getBusinessObject(element);
  return TextFieldEntry({
    element, id, label: 'Condition',
    description: 'CEL (`site_approved`, `attempts < 4`), or FEEL after `=`; empty: none',
    getValue: () => bo.get('conditionExpression')?.get('body') || '',
    setValue: value => {
      const text = (value || '').trim();
      const expression = text
        ? bpmnFactory.create('bpmn:FormalExpression', { body: text })
        : undefined;
      modeling.updateProperties(element, { conditionExpression: expression });
    },
    debounce: fn => fn,
  });
}

function CalledEntry({ element, id }) {
  const modeling = useService('modeling');
  const imported = useService('traceImports');
  const canvas = useService('canvas');
  const bo = getBusinessObject(element);
  const processes = () => {
    const definitions = canvas.getRootElement().businessObject.$parent;
    const roots = (definitions && definitions.get('rootElements')) || [];
    return roots.filter(r => is(r, 'bpmn:Process'));
  };
  return SelectEntry({
    element, id, label: 'Called process',
    description: 'A process of this file (double-click the activity to open it) or of a file it imports',
    getValue: () => bo.get('calledElement') || '',
    setValue: value => modeling.updateProperties(element, { calledElement: value || undefined }),
    getOptions: () => {
      const current = bo.get('calledElement') || '';
      const options = processes().map(p => ({ value: p.id, label: p.name ? `${p.name} (${p.id})` : p.id }));
      for (const p of imported.processes) {
        if (!options.some(o => o.value === p.id)) {
          options.push({ value: p.id, label: `${p.name || p.id} (${p.id}, from ${p.file})` });
        }
      }
      if (current && !options.some(o => o.value === current)) {
        options.unshift({ value: current, label: `${current} (not in this file)` });
      }
      return [{ value: '', label: '(none)' }, ...options];
    },
  });
}

function ScriptEntry({ element, id }) {
  const modeling = useService('modeling');
  const bo = getBusinessObject(element);
  return TextAreaEntry({
    element, id, label: 'Script (CEL)',
    description: 'One assignment per line: `attempts = attempts + 1`',
    getValue: () => bo.get('script') || '',
    setValue: value => modeling.updateProperties(element, {
      script: value || undefined, scriptFormat: bo.get('scriptFormat') || 'cel' }),
    debounce: fn => fn,
    rows: 4,
  });
}

/** The multi-instance characteristics of an activity, or undefined. */
function multiInstance(element) {
  const l = getBusinessObject(element).get('loopCharacteristics');
  return l && is(l, 'bpmn:MultiInstanceLoopCharacteristics') ? l : undefined;
}

/** Its `zeebe:loopCharacteristics` (Camunda 8's items, which the executive reads). */
function zeebeLoop(loop) {
  const ext = loop.get('extensionElements');
  return ext && ext.get('values').find(v => is(v, 'zeebe:LoopCharacteristics'));
}

/** Sets `attribute` of the activity's `zeebe:loopCharacteristics`, creating it if needed. */
function setLoop(element, bpmnFactory, commandStack, attribute, value) {
  const { value: z, cmds } = withExtension(element, multiInstance(element),
    'zeebe:LoopCharacteristics', bpmnFactory);
  cmds.push({ cmd: 'element.updateModdleProperties',
    context: { element, moddleElement: z, properties: { [attribute]: value || undefined } } });
  commandStack.execute('properties-panel.multi-command-executor', cmds);
}

function loopEntry(attribute, label, description, feel) {
  return function LoopEntry({ element, id }) {
    const bpmnFactory = useService('bpmnFactory');
    const commandStack = useService('commandStack');
    return TextFieldEntry({
      element, id, label, description,
      getValue: () => {
        const v = zeebeLoop(multiInstance(element))?.get(attribute) || '';
        return feel ? v.replace(/^=\s*/, '') : v;
      },
      setValue: value => {
        const text = (value || '').trim();
        setLoop(element, bpmnFactory, commandStack, attribute,
          text && feel ? `= ${text}` : text);
      },
      debounce: fn => fn,
    });
  };
}

const CollectionEntry = loopEntry('inputCollection', 'Collection',
  'The list of items, one instance each (FEEL: `sites`)', true);
const ElementEntry = loopEntry('inputElement', 'Element variable',
  'The name each instance reads its item as (`site`)', false);
const OutputEntry = loopEntry('outputCollection', 'Output collection',
  'The variable that collects each instance\'s output, in order', false);

/** The timer definition of an event, its kind (`timeDate`, …) and its text. */
function timerOf(element) {
  const defs = getBusinessObject(element).get('eventDefinitions') || [];
  const timer = defs.find(d => is(d, 'bpmn:TimerEventDefinition'));
  if (!timer) return undefined;
  const kind = ['timeDate', 'timeCycle', 'timeDuration'].find(k => timer.get(k) !== undefined);
  return kind && { kind, value: timer.get(kind).get('body') || '' };
}

function TimerPreview({ element }) {
  const timer = timerOf(element);
  const [shown, setShown] = useState({ text: '', bad: false });
  const kind = timer && timer.kind;
  const value = timer && timer.value;
  useEffect(() => {
    if (!kind) return undefined;
    let live = true;
    fetch('/api/timer', {
      method: 'POST', headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify({ kind, value }),
    }).then(async r => {
      const b = await r.json();
      if (!live) return;
      setShown(r.ok
        ? { text: `${b.summary}${b.firings.length ? `; first: ${b.firings.join(', ')}` : ''}`, bad: false }
        : { text: b.error, bad: true });
    }).catch(e => live && setShown({ text: e.message, bad: true }));
    return () => { live = false; };
  }, [kind, value]);
  if (!kind) return null;
  return (
    <div class="bio-properties-panel-entry trace-timer-preview" data-entry-id="trace-timer-preview">
      <p class={shown.bad ? 'bio-properties-panel-error' : ''}>{shown.text}</p>
    </div>
  );
}

/** The selected element's problems from the last check, redrawn after each check. */
function ProblemsEntry({ element }) {
  const eventBus = useService('eventBus');
  const problems = useService('traceProblems');
  const [, setChecks] = useState(0);
  useEffect(() => {
    const checked = () => setChecks(n => n + 1);
    eventBus.on('trace.checked', checked);
    return () => eventBus.off('trace.checked', checked);
  }, [eventBus]);
  const mine = problems.of(element.id);
  return (
    <div class="bio-properties-panel-entry trace-element-problems" data-entry-id="trace-element-problems">
      {mine.length
        ? <ul>{mine.map(d => <li class={`problem ${d.severity === 'error' ? 'error' : 'warning'}`}
          data-code={d.code}>{d.severity} {d.code}: {d.message}</li>)}</ul>
        : <p>None found by the last check.</p>}
    </div>
  );
}

function DrawingProvider(propertiesPanel) {
  this.getGroups = element => groups => {
    if (element.businessObject && element.businessObject.$type !== 'bpmn:Definitions') {
      groups.splice(1, 0, { id: 'trace-problems', label: 'Problems', entries: [
        { id: 'trace-element-problems', element, component: ProblemsEntry },
      ] });
    }
    if (conditional(element)) {
      groups.splice(1, 0, { id: 'trace-condition', label: 'Condition', entries: [
        { id: 'trace-condition-expr', element, component: ConditionEntry, isEdited: isTextFieldEntryEdited },
      ] });
    }
    if (is(element, 'bpmn:CallActivity')) {
      groups.splice(1, 0, { id: 'trace-called', label: 'Called process', entries: [
        { id: 'trace-called-process', element, component: CalledEntry, isEdited: isSelectEntryEdited },
      ] });
    }
    if (is(element, 'bpmn:ScriptTask')) {
      groups.splice(1, 0, { id: 'trace-script', label: 'Script', entries: [
        { id: 'trace-script-body', element, component: ScriptEntry, isEdited: isTextAreaEntryEdited },
      ] });
    }
    if (multiInstance(element)) {
      groups.splice(1, 0, { id: 'trace-loop', label: 'Multi-instance items', entries: [
        { id: 'trace-loop-collection', element, component: CollectionEntry, isEdited: isTextFieldEntryEdited },
        { id: 'trace-loop-element', element, component: ElementEntry, isEdited: isTextFieldEntryEdited },
        { id: 'trace-loop-output', element, component: OutputEntry, isEdited: isTextFieldEntryEdited },
      ] });
    }
    const timer = groups.find(g => g.id === 'timer');
    if (timer && timerOf(element)) {
      timer.entries.push({ id: 'trace-timer-preview', element, component: TimerPreview });
    }
    return groups;
  };
  propertiesPanel.registerProvider(400, this);
}
DrawingProvider.$inject = ['propertiesPanel'];

export default {
  __init__: ['traceDrawingProvider'],
  traceDrawingProvider: ['type', DrawingProvider],
};
