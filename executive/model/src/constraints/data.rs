//! The static constraints on data: items and their equivalence (§10.3.3, §10.4.1), data
//! associations, ioSpecifications and their sets, a call activity's data against what it calls,
//! multi-instance data, io bindings of operations, and the data of events.

use super::*;

/// The item definition an item-aware element carries: its own `itemSubjectRef`, or that of
/// the data object or data store a reference to one names.
pub(super) fn item_ref<'d>(ix: &Index<'d, '_>, el: &'d Element<'d>) -> Option<&'d str> {
    if let Some(item) = el.attr("itemSubjectRef") {
        return Some(local_ref(item));
    }
    let target = match el.name {
        "dataObjectReference" => el.attr("dataObjectRef"),
        "dataStoreReference" => el.attr("dataStoreRef"),
        _ => None,
    }?;
    ix.get(local_ref(target))?
        .attr("itemSubjectRef")
        .map(local_ref)
}

/// Two item definitions are equivalent (the word of §10.3.3 and §10.4.1) when they are one,
/// or name the same structure and agree on being a collection; an item definition without a
/// `structureRef` is equivalent to itself only.
pub(super) fn equivalent(ix: &Index<'_, '_>, a: &str, b: &str) -> bool {
    if a == b {
        return true;
    }
    match (ix.get(a), ix.get(b)) {
        (Some(x), Some(y)) => {
            x.attr("structureRef").is_some()
                && x.attr("structureRef").map(local_ref) == y.attr("structureRef").map(local_ref)
                && x.attr("isCollection").unwrap_or("false")
                    == y.attr("isCollection").unwrap_or("false")
        }
        // A name that resolves to nothing is reported as a dangling reference.
        _ => true,
    }
}

/// A task's data against the messages it sends or receives: the data `kind` (`dataInput`,
/// `dataOutput`) of `task` must carry an item equivalent to `message`'s.
pub(super) fn data_carries(
    task: &Element,
    kind: &str,
    message: &Element,
    ix: &Index<'_, '_>,
    (code, rule, what): (&'static str, &'static str, &str),
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let Some(item) = message.attr("itemRef").map(local_ref) else {
        return;
    };
    let data: Vec<&Element> = task
        .bpmn_child("ioSpecification")
        .map(|io| io.bpmn_children(kind).collect())
        .unwrap_or_default();
    let carried: Vec<&str> = data
        .iter()
        .filter_map(|d| d.attr("itemSubjectRef").map(local_ref))
        .collect();
    if carried.is_empty() || carried.iter().any(|c| equivalent(ix, c, item)) {
        return;
    }
    err(
        code,
        rule,
        format!(
            "{} `{}`: no {kind} carries an item equivalent to `{item}`, the item of {what} `{}` ({}); the message's content is passed as it comes",
            task.name,
            task.attr("id").unwrap_or_default(),
            message.attr("id").unwrap_or_default(),
            carried.join(", ")
        ),
    );
}

/// A service task that calls an operation (§10.3.3): its data input carries the item of the
/// operation's in-message, its data output the item of the out-message (EXT.045).
pub(super) fn operation_items(
    el: &Element,
    ix: &Index<'_, '_>,
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let Some(op) = ix.named(el, "operationRef") else {
        return;
    };
    for (child, kind, rule, what) in [
        (
            "inMessageRef",
            "dataInput",
            "§10.3.3",
            "the operation's in-message",
        ),
        (
            "outMessageRef",
            "dataOutput",
            "EXT.045",
            "the operation's out-message",
        ),
    ] {
        if let Some(message) = op
            .bpmn_child(child)
            .and_then(|m| ix.get(local_ref(m.trimmed_text())))
        {
            data_carries(el, kind, message, ix, ("item-mismatch", rule, what), err);
        }
    }
}

/// A send task's data input carries the item of the message it sends, a receive task's data
/// output that of the message it receives (§10.3.3).
pub(super) fn message_items(
    el: &Element,
    ix: &Index<'_, '_>,
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let Some(message) = ix.named(el, "messageRef") else {
        return;
    };
    let (kind, what) = if el.name == "sendTask" {
        ("dataInput", "the message sent")
    } else {
        ("dataOutput", "the message received")
    };
    data_carries(
        el,
        kind,
        message,
        ix,
        ("item-mismatch", "§10.3.3", what),
        err,
    );
}

pub(super) fn data_association(
    el: &Element,
    owner: Option<&Element>,
    ix: &Index<'_, '_>,
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let sources: Vec<&str> = el
        .bpmn_children("sourceRef")
        .map(|r| local_ref(r.text))
        .collect();
    // §10.4.1: "The ItemDefinition from the sourceRef and targetRef MUST have the same
    // ItemDefinition or the DataAssociation MUST have a transformation Expression".
    let target = el
        .bpmn_child("targetRef")
        .and_then(|t| ix.get(local_ref(t.trimmed_text())));
    if let ([source], Some(target)) = (sources.as_slice(), target)
        && el.bpmn_child("transformation").is_none()
        && el.bpmn_child("assignment").is_none()
        && let Some(source) = ix.get(source)
        && let (Some(a), Some(b)) = (item_ref(ix, source), item_ref(ix, target))
        && !equivalent(ix, a, b)
    {
        err(
            "item-mismatch",
            "§10.4.1",
            format!(
                "the data association from `{}` (item `{a}`) to `{}` (item `{b}`) joins items that are not equivalent, without a transformation; the value is passed as it is",
                source.attr("id").unwrap_or_default(),
                target.attr("id").unwrap_or_default()
            ),
        );
    }
    if sources.len() > 1 && el.bpmn_child("transformation").is_none() {
        err(
            "many-sources",
            "EXT.092",
            "a data association without a transformation has a single sourceRef".to_owned(),
        );
    }
    let input = el.name == "dataInputAssociation";
    let owner_id = owner.and_then(|o| o.attr("id")).unwrap_or_default();
    // An input (output) the owner declares in its ioSpecification, or directly as events do.
    // Looked up, not scanned for: an activity may hold thousands of associations.
    let own = |r: &str, kind: &str| {
        kind == if input { "dataInput" } else { "dataOutput" }
            && ix
                .holder(r)
                .zip(owner)
                .is_some_and(|((holder, _), o)| std::ptr::eq(holder, o))
    };
    let outside: Vec<&str> = if input {
        sources.clone()
    } else {
        el.bpmn_children("targetRef")
            .map(|r| local_ref(r.text))
            .collect()
    };
    // The end inside the owner: an input association writes a data input (or a property, as
    // bpmn-js draws it), an output association reads a data output (§10.4.1).
    let inside: Vec<&str> = if input {
        el.bpmn_children("targetRef")
            .map(|r| local_ref(r.text))
            .collect()
    } else {
        sources.clone()
    };
    let (wrong, kind, way, what) = if input {
        ("dataOutput", "input", "writes", "output")
    } else {
        ("dataInput", "output", "reads", "input")
    };
    for r in inside {
        if ix.get(r).is_some_and(|end| end.name == wrong) {
            err(
                "bad-data-association",
                "§10.4.1",
                format!("data {kind} association {way} `{r}`, a data {what}"),
            );
        }
    }
    for r in outside {
        let Some(target) = ix.get(r) else {
            continue;
        };
        let kind = target.name;
        if input && kind == "dataOutput" {
            err(
                "bad-data-association",
                "EXT.082",
                format!("data input association reads `{r}`, a data output, which cannot be read"),
            );
        }
        if !input && kind == "dataInput" {
            err(
                "bad-data-association",
                "EXT.080",
                format!(
                    "data output association writes `{r}`, a data input, which cannot be written"
                ),
            );
        }
        // A sub-process's own data inputs/outputs are not visible to the activities inside it.
        if matches!(kind, "dataInput" | "dataOutput") && !own(r, kind) {
            // Declared in its process's ioSpecification: the process's data, visible inside it.
            let holder_is_process = ix.holder(r).is_some_and(|(holder, in_spec)| {
                in_spec
                    && holder.name == "process"
                    && ix
                        .process_of(r)
                        .is_some_and(|p| holder.attr("id") == Some(p))
            });
            if !holder_is_process {
                err(
                    "invisible-data",
                    "EXT.079",
                    format!(
                        "`{r}` is a data {} of another activity and is not visible from `{owner_id}`",
                        if kind == "dataInput" {
                            "input"
                        } else {
                            "output"
                        }
                    ),
                );
            }
        }
    }
}

pub(super) fn io_specification(
    el: &Element,
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let ids = |set: &Element, child: &str| -> BTreeSet<String> {
        set.bpmn_children(child)
            .map(|r| local_ref(r.text).to_owned())
            .collect()
    };
    for (set, main, rules) in [
        (
            "inputSet",
            "dataInputRefs",
            [
                ("optionalInputRefs", "EXT.085"),
                ("whileExecutingInputRefs", "EXT.086"),
            ],
        ),
        (
            "outputSet",
            "dataOutputRefs",
            [
                ("optionalOutputRefs", "EXT.089"),
                ("whileExecutingOutputRefs", "EXT.090"),
            ],
        ),
    ] {
        for s in el.bpmn_children(set) {
            let listed = ids(s, main);
            for (child, c) in rules {
                for r in ids(s, child) {
                    if !listed.contains(&r) {
                        err(
                            "io-set",
                            c,
                            format!(
                                "`{r}` is listed in {child} but not in the {main} of the same {set}"
                            ),
                        );
                    }
                }
            }
        }
    }
    // Every data input/output belongs to at least one input/output set (EXT.088).
    for (item, set, refs) in [
        ("dataInput", "inputSet", "dataInputRefs"),
        ("dataOutput", "outputSet", "dataOutputRefs"),
    ] {
        let listed: BTreeSet<String> = el.bpmn_children(set).flat_map(|s| ids(s, refs)).collect();
        for d in el.bpmn_children(item) {
            if let Some(id) = d.attr("id")
                && !listed.contains(id)
            {
                err(
                    "io-set",
                    "EXT.088",
                    format!("{item} `{id}` is not part of any {set}"),
                );
            }
        }
    }
    // inputSet.outputSetRefs and outputSet.inputSetRefs must mirror each other (EXT.087).
    let sets = |name: &str| -> Vec<(String, BTreeSet<String>)> {
        let other = if name == "inputSet" {
            "outputSetRefs"
        } else {
            "inputSetRefs"
        };
        el.bpmn_children(name)
            .map(|s| (s.attr("id").unwrap_or_default().to_owned(), ids(s, other)))
            .collect()
    };
    let (ins, outs) = (sets("inputSet"), sets("outputSet"));
    for (i, i_refs) in &ins {
        for o in i_refs {
            if !outs
                .iter()
                .any(|(oid, o_refs)| oid == o && o_refs.contains(i))
            {
                err(
                    "io-set",
                    "EXT.087",
                    format!("inputSet `{i}` names outputSet `{o}`, which does not name it back"),
                );
            }
        }
    }
    for (o, o_refs) in &outs {
        for i in o_refs {
            if !ins
                .iter()
                .any(|(iid, i_refs)| iid == i && i_refs.contains(o))
            {
                err(
                    "io-set",
                    "EXT.087",
                    format!("outputSet `{o}` names inputSet `{i}`, which does not name it back"),
                );
            }
        }
    }
}

/// Two item-aware elements carry the same item: one item definition, or two with the same
/// `structureRef` and collection flag. Where either names no item (or one that does not
/// resolve), nothing is known against it.
pub(super) fn same_item(ix: &Index<'_, '_>, a: &Element, b: &Element) -> bool {
    match (item_of(ix, a), item_of(ix, b)) {
        (Some(x), Some(y)) => {
            std::ptr::eq(x, y)
                || (x.attr("structureRef").is_some()
                    && x.attr("structureRef") == y.attr("structureRef")
                    && x.attr("isCollection") == y.attr("isCollection"))
        }
        _ => true,
    }
}

/// A call activity's data must match what it calls (§10.3.6: "the elements contained in the
/// Call Activity's InputOutputSpecification MUST exactly match the elements contained in the
/// referenced CallableElement"): as many data inputs and outputs, in order, each with the same
/// item. Variables are passed by name, so a mismatch is a rule bent harmlessly (`--strict`
/// refuses it).
pub(super) fn call_data(
    el: &Element,
    ix: &Index<'_, '_>,
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let Some(callee) = ix
        .named(el, "calledElement")
        .filter(|c| c.name == "process" || c.name.starts_with("global"))
    else {
        return;
    };
    fn data<'a, 'b>(e: &'a Element<'b>, kind: &str) -> Vec<&'a Element<'b>> {
        e.bpmn_child("ioSpecification")
            .map(|io| io.bpmn_children(kind).collect())
            .unwrap_or_default()
    }
    let call = el.attr("id").unwrap_or_default();
    let called = callee.attr("id").unwrap_or_default();
    for (kind, what) in [("dataInput", "data input"), ("dataOutput", "data output")] {
        let (mine, theirs) = (data(el, kind), data(callee, kind));
        if mine.len() != theirs.len() {
            err(
                "call-data-mismatch",
                "§10.3.6",
                format!(
                    "callActivity `{call}` declares {} {what}(s), the <{}> `{called}` it calls {}: a call's data must match what it calls exactly",
                    mine.len(),
                    callee.name,
                    theirs.len()
                ),
            );
            continue;
        }
        for (k, (a, b)) in mine.iter().zip(&theirs).enumerate() {
            if !same_item(ix, a, b) {
                err(
                    "call-data-mismatch",
                    "§10.3.6",
                    format!(
                        "{what} {} of callActivity `{call}` (`{}`) carries item `{}`, the one of `{called}` (`{}`) item `{}`",
                        k + 1,
                        a.attr("id").unwrap_or_default(),
                        a.attr("itemSubjectRef").unwrap_or_default(),
                        b.attr("id").unwrap_or_default(),
                        b.attr("itemSubjectRef").unwrap_or_default()
                    ),
                );
            }
        }
    }
}

pub(super) fn item_of<'d>(ix: &Index<'d, '_>, el: &Element) -> Option<&'d Element<'d>> {
    let r = el.attr("itemSubjectRef")?;
    ix.get(local_ref(r)).filter(|i| i.name == "itemDefinition")
}

pub(super) fn multi_instance(
    el: &Element,
    activity: Option<&Element>,
    executable: bool,
    ix: &Index<'_, '_>,
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let Some(activity) = activity else { return };
    let spec_items = |kind: &'static str| -> Vec<&Element> {
        activity
            .bpmn_children("ioSpecification")
            .flat_map(|s| s.bpmn_children(kind))
            .collect::<Vec<_>>()
    };
    for (reference, kind, item, c_exec, c_type) in [
        (
            "loopDataInputRef",
            "dataInput",
            "inputDataItem",
            "EXT.068",
            "EXT.070",
        ),
        (
            "loopDataOutputRef",
            "dataOutput",
            "outputDataItem",
            "EXT.068",
            "EXT.069",
        ),
    ] {
        let Some(r) = el
            .bpmn_child(reference)
            .map(|r| local_ref(r.text).to_owned())
        else {
            continue;
        };
        let target = spec_items(kind)
            .into_iter()
            .find(|d| d.attr("id") == Some(r.as_str()));
        if executable
            && target.is_none()
            && reference == "loopDataInputRef"
            && ix.kind(&r).is_some()
            && ix.kind(&r) != Some("property")
            && ix.kind(&r) != Some("dataObject")
        {
            err(
                "bad-loop-data",
                c_exec,
                format!("{reference} `{r}` must name a {kind} of the activity's ioSpecification"),
            );
        }
        let (Some(coll), Some(elem)) = (target, el.bpmn_child(item)) else {
            continue;
        };
        if elem.attr("isCollection") == Some("true") {
            err(
                "bad-loop-data",
                c_type,
                format!("{item} must be a single element of `{r}`, not a collection"),
            );
        }
        if let (Some(ci), Some(ei)) = (item_of(ix, coll), item_of(ix, elem))
            && ci.attr("structureRef") != ei.attr("structureRef")
        {
            err(
                "bad-loop-data",
                c_type,
                format!("{item} has another structure than the elements of `{r}`"),
            );
        }
    }
}

/// An ioBinding must bind a data input and output whose items match the operation's messages.
pub(super) fn io_binding(
    el: &Element,
    ix: &Index<'_, '_>,
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let Some(op) = ix.named(el, "operationRef") else {
        return;
    };
    for (data_attr, msg_child) in [
        ("inputDataRef", "inMessageRef"),
        ("outputDataRef", "outMessageRef"),
    ] {
        let data = ix.named(el, data_attr);
        let msg = op
            .bpmn_child(msg_child)
            .and_then(|m| ix.get(local_ref(m.text)));
        if let (Some(data), Some(msg)) = (data, msg) {
            let data_item = data.attr("itemSubjectRef").map(local_ref);
            let msg_item = msg.attr("itemRef").map(local_ref);
            if data_item.is_some() && msg_item.is_some() && data_item != msg_item {
                err(
                    "bad-io-binding",
                    "EXT.065",
                    format!(
                        "{data_attr} `{}` does not carry the item of the operation's {msg_child}",
                        data.attr("id").unwrap_or_default()
                    ),
                );
            }
        }
    }
}

/// Events with data: one data output (catch) or input (throw) per event definition, whose item
/// matches the definition's item (EXT.093, EXT.094).
pub(super) fn event_data(root: &Element, ix: &Index<'_, '_>, sink: &mut Sink) {
    let mut stack = vec![root];
    while let Some(el) = stack.pop() {
        if el.ns != Ns::Bpmn {
            continue;
        }
        stack.extend(el.children.iter());
        let catch = matches!(
            el.name,
            "startEvent" | "intermediateCatchEvent" | "boundaryEvent"
        );
        let throw = matches!(el.name, "endEvent" | "intermediateThrowEvent");
        if !catch && !throw {
            continue;
        }
        let data: Vec<&Element> = el
            .bpmn_children(if catch { "dataOutput" } else { "dataInput" })
            .collect();
        if data.is_empty() {
            continue;
        }
        let defs: Vec<&Element> = el
            .children
            .iter()
            .filter(|c| c.ns == Ns::Bpmn)
            .filter_map(|c| {
                if c.name == "eventDefinitionRef" {
                    ix.get(local_ref(c.text))
                } else {
                    c.name.ends_with("EventDefinition").then_some(c)
                }
            })
            .collect();
        if defs.len() != data.len() {
            let msg = format!(
                "the event has {} event definitions but {} data {}s: each definition should have its own; data without one is unused",
                defs.len(),
                data.len(),
                if catch { "output" } else { "input" }
            );
            sink.bent("event-data", "EXT.093", el.offset, el.attr("id"), msg);
        }
        for (d, data) in defs.iter().zip(&data) {
            let item = match d.name {
                "messageEventDefinition" => d
                    .attr("messageRef")
                    .and_then(|m| ix.get(local_ref(m)))
                    .and_then(|m| m.attr("itemRef")),
                "errorEventDefinition" => d
                    .attr("errorRef")
                    .and_then(|m| ix.get(local_ref(m)))
                    .and_then(|m| m.attr("structureRef")),
                "escalationEventDefinition" => d
                    .attr("escalationRef")
                    .and_then(|m| ix.get(local_ref(m)))
                    .and_then(|m| m.attr("structureRef")),
                "signalEventDefinition" => d
                    .attr("signalRef")
                    .and_then(|m| ix.get(local_ref(m)))
                    .and_then(|m| m.attr("structureRef")),
                _ => None,
            };
            if let (Some(item), Some(own)) = (item, data.attr("itemSubjectRef")) {
                // Item definitions are equivalent when they name the same structure.
                let structure = |i: &str| {
                    ix.get(local_ref(i))
                        .and_then(|d| d.attr("structureRef"))
                        .map(local_ref)
                        .unwrap_or(local_ref(i))
                        .to_owned()
                };
                if structure(item) != structure(own) {
                    let msg = format!(
                        "the data of the {} must have its item `{}`, not `{}`",
                        d.name,
                        local_ref(item),
                        local_ref(own)
                    );
                    sink.error("event-data", el.offset, el.attr("id"), msg)
                        .constraint("EXT.094");
                }
            }
        }
    }
}
