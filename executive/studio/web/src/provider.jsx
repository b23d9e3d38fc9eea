// The TRACE groups of the properties panel: a task's action chosen from the catalogues, and its
// goal inputs and result outputs as `trace:input` / `trace:output` rows whose paths are checked
// against the action's goal and result fields as they are typed; on an error boundary, the
// codes the task's action declares. What it writes is the `trace:task` binding the executive
// reads (docs/guide/planning.md, "Writing missions").
import { is, getBusinessObject } from 'bpmn-js/lib/util/ModelUtil';
import {
  ListGroup, SelectEntry, TextFieldEntry, isSelectEntryEdited, isTextFieldEntryEdited,
} from '@bpmn-io/properties-panel';
import { useService } from 'bpmn-js-properties-panel';

/** The types a `trace:input`/`trace:output` may declare. */
const TYPES = ['', 'string', 'int', 'f64', 'bool', 'timestamp', 'json',
  '[string]', '[int]', '[f64]', '[bool]', '[json]'];

const TASKS = ['bpmn:ServiceTask', 'bpmn:UserTask', 'bpmn:SendTask', 'bpmn:ScriptTask',
  'bpmn:BusinessRuleTask', 'bpmn:Task'];

export function traceTask(element) {
  const ext = getBusinessObject(element).get('extensionElements');
  return ext && ext.get('values').find(v => is(v, 'trace:Task'));
}

/** The type a catalogue message declares at a dotted path, or undefined. */
export function typeAt(fields, path) {
  let here = fields;
  const parts = path.split('.');
  for (let i = 0; i < parts.length; i += 1) {
    if (!here || typeof here !== 'object') return undefined;
    const t = here[parts[i]];
    if (t === undefined) return undefined;
    if (i === parts.length - 1) return t;
    here = t;
  }
  return undefined;
}

/** Every leaf path of a catalogue message (`selected_site.site_id`), with its type. */
export function leaves(fields, prefix = '') {
  return Object.entries(fields || {}).flatMap(([name, t]) => (
    t && typeof t === 'object' ? leaves(t, `${prefix}${name}.`) : [[`${prefix}${name}`, t]]
  ));
}

const shown = t => (typeof t === 'string' ? t : 'message');

/**
 * Commands that give moddle element `owner` (of diagram element `element`) an extension of
 * `type` (created with `props`), and that extension: one undo step with the change that needs it.
 */
export function withExtension(element, owner, type, bpmnFactory, props = {}) {
  const cmds = [];
  let ext = owner.get('extensionElements');
  if (!ext) {
    ext = bpmnFactory.create('bpmn:ExtensionElements', { values: [] });
    ext.$parent = owner;
    cmds.push({ cmd: 'element.updateModdleProperties',
      context: { element, moddleElement: owner, properties: { extensionElements: ext } } });
  }
  let value = ext.get('values').find(v => is(v, type));
  if (!value) {
    value = bpmnFactory.create(type, props);
    value.$parent = ext;
    cmds.push({ cmd: 'element.updateModdleProperties',
      context: { element, moddleElement: ext, properties: { values: [...ext.get('values'), value] } } });
  }
  return { value, cmds };
}

/** Commands that give `element` a `trace:task`, and the task. */
function withTask(element, bpmnFactory) {
  const { value, cmds } = withExtension(element, getBusinessObject(element), 'trace:Task',
    bpmnFactory, { inputs: [], outputs: [] });
  return { task: value, cmds };
}

function run(commandStack, cmds) {
  commandStack.execute('properties-panel.multi-command-executor', cmds);
}

function ResourceEntry({ element, id }) {
  const bpmnFactory = useService('bpmnFactory');
  const commandStack = useService('commandStack');
  const catalogue = useService('traceCatalogue');
  const current = traceTask(element)?.get('resource') || '';
  const options = () => {
    const names = catalogue.actions.map(a => a.name);
    if (current && !names.includes(current)) names.unshift(current);
    return [{ value: '', label: '(none)' },
      ...names.map(n => ({ value: n, label: catalogue.action(n) ? n : `${n} (in no catalogue)` }))];
  };
  return SelectEntry({
    element, id, label: 'Action',
    getValue: () => traceTask(element)?.get('resource') || '',
    setValue: value => {
      const { task, cmds } = withTask(element, bpmnFactory);
      cmds.push({ cmd: 'element.updateModdleProperties',
        context: { element, moddleElement: task, properties: { resource: value || undefined } } });
      run(commandStack, cmds);
    },
    getOptions: options,
  });
}

function DescriptionEntry({ element }) {
  const catalogue = useService('traceCatalogue');
  const action = catalogue.action(traceTask(element)?.get('resource') || '');
  if (!action) return null;
  const errors = Object.keys(action.errors || {});
  return (
    <div class="bio-properties-panel-entry trace-action-help" data-entry-id="trace-action-help">
      <p>{action.description}</p>
      {errors.length ? <p>Errors it may raise: {errors.join(', ')}</p> : null}
    </div>
  );
}

/** The action bound to `element` in the catalogue, and the message a row of `which` reads. */
function messageOf(catalogue, element, which) {
  const action = catalogue.action(traceTask(element)?.get('resource') || '');
  return { action, fields: action && (which === 'inputs' ? action.goal : action.result) };
}

// A row's entries are module-level components (a component made anew on each render would be
// a new component to preact, and its field would be replaced under the user's cursor).

/** The message path of a row: a goal field (inputs) or a result field (outputs). */
function RowPath({ element, id, row, which }) {
  const modeling = useService('modeling');
  const debounce = useService('debounceInput');
  const catalogue = useService('traceCatalogue');
  const goal = which === 'inputs';
  const key = goal ? 'target' : 'source';
  const { action, fields } = messageOf(catalogue, element, which);
  return TextFieldEntry({
    element, id, debounce,
    label: goal ? 'Goal field' : 'Result field',
    description: fields ? `one of: ${leaves(fields).map(([p, t]) => `${p} (${shown(t)})`).join(', ')}` : undefined,
    getValue: () => row.get(key) || '',
    setValue: v => modeling.updateModdleProperties(element, row, { [key]: v }),
    validate: v => {
      if (!v) return 'required';
      if (fields && typeAt(fields, v) === undefined) {
        return `${v} is not a ${goal ? 'goal' : 'result'} field of ${action.name}`;
      }
      return null;
    },
  });
}

/** The other side of a row: an expression (inputs) or a variable (outputs). */
function RowExpr({ element, id, row, which }) {
  const modeling = useService('modeling');
  const debounce = useService('debounceInput');
  const goal = which === 'inputs';
  const key = goal ? 'source' : 'target';
  return TextFieldEntry({
    element, id, debounce,
    label: goal ? 'Value (expression)' : 'Variable',
    getValue: () => row.get(key) || '',
    setValue: v => modeling.updateModdleProperties(element, row, { [key]: v }),
    validate: v => (v ? null : 'required'),
  });
}

/** A row's declared type, the catalogue's marked. */
function RowType({ element, id, row, which }) {
  const modeling = useService('modeling');
  const catalogue = useService('traceCatalogue');
  const path = row.get(which === 'inputs' ? 'target' : 'source') || '';
  return SelectEntry({
    element, id, label: 'Type',
    getValue: () => row.get('type') || '',
    setValue: v => modeling.updateModdleProperties(element, row, { type: v || undefined }),
    getOptions: () => {
      const { fields } = messageOf(catalogue, element, which);
      const declared = fields && typeAt(fields, path);
      const types = [...TYPES];
      const own = row.get('type');
      if (own && !types.includes(own)) types.push(own);
      return types.map(t => ({
        value: t,
        label: t ? (declared && shown(declared).replace(/\?$/, '') === t ? `${t} (declared)` : t) : '(from the catalogue)',
      }));
    },
  });
}

function rowEntries(element, row, which, idPrefix) {
  return [
    { id: `${idPrefix}-path`, component: RowPath, row, which, isEdited: isTextFieldEntryEdited },
    { id: `${idPrefix}-expr`, component: RowExpr, row, which, isEdited: isTextFieldEntryEdited },
    { id: `${idPrefix}-type`, component: RowType, row, which, isEdited: isSelectEntryEdited },
  ];
}

function mappingGroup(element, injector, which) {
  const task = traceTask(element);
  const rows = (task && task.get(which)) || [];
  const bpmnFactory = injector.get('bpmnFactory');
  const commandStack = injector.get('commandStack');
  const catalogue = injector.get('traceCatalogue');
  const goal = which === 'inputs';
  const items = rows.map((row, i) => {
    const id = `${element.id}-trace-${which}-${i}`;
    return {
      id,
      label: goal ? (row.get('target') || '(no field)') : `${row.get('source') || '(no field)'} → ${row.get('target') || '?'}`,
      entries: rowEntries(element, row, which, id),
      autoFocusEntry: `${id}-path`,
      remove: () => {
        const t = traceTask(element);
        run(commandStack, [{ cmd: 'element.updateModdleProperties',
          context: { element, moddleElement: t, properties: { [which]: t.get(which).filter(r => r !== row) } } }]);
      },
    };
  });
  const add = event => {
    event.stopPropagation();
    const { task: t, cmds } = withTask(element, bpmnFactory);
    const action = catalogue.action(t.get('resource') || '');
    // The first field of the action's message not bound yet, typed as the catalogue says.
    const bound = new Set(t.get(which).map(r => r.get(goal ? 'target' : 'source')));
    const next = action && leaves(goal ? action.goal : action.result).find(([p]) => !bound.has(p));
    const props = {};
    if (next) {
      const [path, type] = next;
      props[goal ? 'target' : 'source'] = path;
      props[goal ? 'source' : 'target'] = goal ? '' : path.replace(/\./g, '_');
      if (typeof type === 'string' && TYPES.includes(type.replace(/\?$/, ''))) props.type = type.replace(/\?$/, '');
    }
    const row = bpmnFactory.create(goal ? 'trace:Input' : 'trace:Output', props);
    row.$parent = t;
    cmds.push({ cmd: 'element.updateModdleProperties',
      context: { element, moddleElement: t, properties: { [which]: [...t.get(which), row] } } });
    run(commandStack, cmds);
  };
  return {
    id: `trace-${which}`,
    label: goal ? 'Goal inputs' : 'Result outputs',
    component: ListGroup,
    items,
    add,
    element,
  };
}

/** Error codes the protocol raises for any action (docs/protocol.md §9): catchable undeclared. */
const PROTOCOL_CODES = ['CONNECTOR_LOST', 'REJECTED', 'TYPE_MISMATCH', 'NO_CONNECTOR',
  'NOT_ACCEPTED', 'PROTOCOL_ERROR', 'ABORTED'];

/** The error event definition of an error boundary event, or undefined. */
function errorDefinition(element) {
  if (!is(element, 'bpmn:BoundaryEvent')) return undefined;
  return (getBusinessObject(element).get('eventDefinitions') || [])
    .find(d => is(d, 'bpmn:ErrorEventDefinition'));
}

/**
 * The code an error boundary catches, chosen from what the action of the task it is attached
 * to declares (and the protocol's own codes): the definition's errorRef is set to the
 * `bpmn:Error` of that code, created among the definitions' root elements if there is none.
 */
function ErrorCodeEntry({ element, id }) {
  const bpmnFactory = useService('bpmnFactory');
  const commandStack = useService('commandStack');
  const canvas = useService('canvas');
  const catalogue = useService('traceCatalogue');
  const definition = errorDefinition(element);
  const host = element.host;
  const action = host && catalogue.action(traceTask(host)?.get('resource') || '');
  const declared = Object.entries((action && action.errors) || {});
  const current = definition?.get('errorRef')?.get('errorCode') || '';
  return SelectEntry({
    element, id, label: 'Error code',
    description: action ? `What ${action.name} declares, then the protocol's own codes`
      : 'The task this boundary is on has no action from the catalogues',
    getValue: () => current,
    setValue: code => {
      const cmds = [];
      let error;
      if (code) {
        const definitions = canvas.getRootElement().businessObject.$parent;
        const roots = definitions.get('rootElements');
        error = roots.find(r => is(r, 'bpmn:Error') && r.get('errorCode') === code);
        if (!error) {
          error = bpmnFactory.create('bpmn:Error', {
            errorCode: code, name: (action && action.errors[code]) || code });
          error.$parent = definitions;
          cmds.push({ cmd: 'element.updateModdleProperties',
            context: { element, moddleElement: definitions, properties: { rootElements: [...roots, error] } } });
        }
      }
      cmds.push({ cmd: 'element.updateModdleProperties',
        context: { element, moddleElement: definition, properties: { errorRef: error } } });
      run(commandStack, cmds);
    },
    getOptions: () => {
      const codes = [...declared.map(([c, why]) => ({ value: c, label: `${c} — ${why}` })),
        ...PROTOCOL_CODES.filter(c => !declared.some(([d]) => d === c))
          .map(c => ({ value: c, label: `${c} (protocol)` }))];
      if (current && !codes.some(c => c.value === current)) {
        codes.unshift({ value: current, label: `${current} (not declared by the action)` });
      }
      return [{ value: '', label: '(any error)' }, ...codes];
    },
  });
}

function TracePropertiesProvider(propertiesPanel, injector) {
  this.getGroups = element => groups => {
    if (errorDefinition(element)) {
      groups.splice(1, 0, { id: 'trace-error', label: 'TRACE error', entries: [
        { id: 'trace-error-code', element, component: ErrorCodeEntry, isEdited: isSelectEntryEdited },
      ] });
      return groups;
    }
    if (!TASKS.some(t => is(element, t))) return groups;
    groups.splice(1, 0,
      { id: 'trace-task', label: 'TRACE activity', entries: [
        { id: 'trace-resource', element, component: ResourceEntry, isEdited: isSelectEntryEdited },
        { id: 'trace-action-help', element, component: DescriptionEntry },
      ] },
      mappingGroup(element, injector, 'inputs'),
      mappingGroup(element, injector, 'outputs'));
    return groups;
  };
  propertiesPanel.registerProvider(500, this);
}
TracePropertiesProvider.$inject = ['propertiesPanel', 'injector'];

export default {
  __init__: ['tracePropertiesProvider'],
  tracePropertiesProvider: ['type', TracePropertiesProvider],
};
