#!/usr/bin/env python3
"""A TRACE ground station `py-station` (server `ground`, operator `py-op`), written from
docs/protocol.md alone.

Serves the ground catalogue (action `ground.approve_dig`: the user task goal, and the form
`approve` bool, `comment` string?), takes the user task goal (ACCEPTED, then EXECUTING), and then,
as the operator: (a) answers with a wrongly typed form, (b) answers a user task that is not open,
(c) asks the executive's monitoring state (§8b), (d) answers right, (e) records the reason of the
cancel that closes the task. Every verdict is recorded.

    trace_ground.py --connect tcp/127.0.0.1:7447 --deployment D [--key-root trace] --report FILE

Prints `ready ground py-station — deployment D (keys trace/D/…)` on stdout when it serves; logs
on stderr; writes a JSON report to --report after every notable event. Exits 0 once the
executive's token (`<root>/alive/exec/<mission>`) has been seen and has disappeared, 2 when
nothing happens for 120 s.

The server machinery (goal table, queryables, statuses, liveliness, report) is
trace_protocol.py's; this file holds the catalogue and the operator.
"""

import json
import threading

import trace_protocol
from trace_protocol import enc

SERVER = "ground"
STATION = "py-station"
OPERATOR = "py-op"
ACTION = "ground.approve_dig"
ANSWER_TIMEOUT_S = 10.0

CATALOGUE = {
    "server": SERVER,
    "actions": [
        {
            "name": ACTION,
            "description": "Approve the dig: is the achieved depth good enough?",
            "goal": {"task": "string", "name": "string", "context": "json", "deadline_ms": "int?"},
            "result": {"approve": "bool", "comment": "string?"},
            "feedback": {},
            "errors": {},
        },
    ],
}


class Station(trace_protocol.Server):
    """The ground station: keeps each user task open (EXECUTING) and plays one scripted
    operator session on the first (§8a); records the executive's record lines it cares about."""

    def __init__(self, args):
        super().__init__(
            args,
            CATALOGUE,
            name=f"{SERVER} {STATION}",
            instance=STATION,
            report_fields={
                "station": STATION,
                "operator": OPERATOR,
                "user_tasks": [],
                "verdicts": {},
                "state": None,
                "cancel_reason": None,
                "record": [],
            },
        )
        self.accepted = threading.Event()
        self.operating = False

    def declare(self, session):
        """The executive's record stream (§8b), subscribed before anything is served."""
        return [session.declare_subscriber(f"{self.root}/exec/*/record", self.safe(self.on_record))]

    def action_token(self, action):
        """A station declares only the per-station token of each action (§8a)."""
        return f"{super().action_token(action)}/{STATION}"

    def serving_line(self):
        """The log's serving line, naming the station."""
        return f"station {STATION} {super().serving_line()}"

    def cancel_answered(self, gid, reason, answer):
        """The reason of an accepted cancel says who answered (§8a): recorded."""
        if answer == "ACCEPTED":
            self.report.update(lambda d: d.__setitem__("cancel_reason", reason))

    # ---- the user task on the operator's desk

    def run_activity(self, g):
        """ACCEPTED was published: EXECUTING while the task is on the desk, then the operator."""
        with self.lock:
            if g.status != "ACCEPTED":
                return
            st = self.transition(g, "EXECUTING")
        self.publish_status(g, st)
        f = g.fields
        self.report.update(
            lambda d: d["user_tasks"].append(
                {
                    "goal_id": g.gid,
                    "task": f.get("task"),
                    "name": f.get("name"),
                    "deadline_ms": f.get("deadline_ms"),
                    "context": f.get("context"),
                }
            )
        )
        with self.lock:
            if self.operating:
                return  # one scripted operator session per station run
            self.operating = True
        try:
            self.operate(g)
        except Exception as e:  # noqa: BLE001
            self.log.exception("operator on %s", g.gid)
            self.error("operator on %s failed: %r", g.gid, e)

    def answer_key(self, gid):
        """`<root>/act/ground/<action>/answer/<goal_id>`, the executive's answer queryable (§8a)."""
        return f"{self.root}/act/{SERVER}/{ACTION}/answer/{gid}"

    def answer(self, label, gid, fields):
        """Send an answer query (§8a) and record the verdict."""
        key = self.answer_key(gid)
        payload = {"goal_id": gid, "fields": fields, "operator": OPERATOR, "station": STATION}
        self.log.info("answer %s on %s: %s", label, key, json.dumps(fields))
        verdict = self.query(key, payload, "answer", ANSWER_TIMEOUT_S)
        self.log.info("verdict %s: %s", label, json.dumps(verdict))
        self.touch()
        self.report.update(
            lambda d: d["verdicts"].__setitem__(label, {"goal_id": gid, "fields": fields, "key": key, **verdict})
        )
        return verdict

    def query(self, key, payload, kind, timeout):
        """A get with a JSON payload: {"replies": [...], "errors": [...]} (each parsed if it can be)."""
        out = {"replies": [], "errors": []}
        try:
            replies = self.session.get(
                key,
                payload=json.dumps(payload) if payload is not None else None,
                encoding=enc(kind) if payload is not None else None,
                timeout=timeout,
            )
            for r in replies:
                if r.ok is not None:
                    raw = r.ok.payload.to_bytes()
                    try:
                        out["replies"].append(json.loads(raw))
                    except (UnicodeDecodeError, json.JSONDecodeError):
                        out["replies"].append({"unparsed": raw.decode("utf-8", "replace")})
                        self.error("unreadable reply on %s: %r", key, raw[:200])
                else:
                    out["errors"].append(r.err.payload.to_bytes().decode("utf-8", "replace"))
        except Exception as e:  # noqa: BLE001
            out["errors"].append(f"query failed: {e!r}")
        if not out["replies"] and not out["errors"]:
            out["errors"].append("no reply")
        if len(out["replies"]) == 1:
            out["reply"] = out["replies"][0]
        return out

    def operate(self, g):
        """The scripted operator session on user task `g`: steps (a) to (e) of the module doc."""
        mission = g.gid.rsplit(".", 3)[0]
        # The task is open from the moment the executive sent its goal (§8a): answer at once.
        # (a) a wrongly typed form
        self.waiting_for = f"the verdict on the wrongly typed answer to {g.gid}"
        self.answer("wrong_type", g.gid, {"approve": "yes"})
        # (b) an answer for a user task that is not open
        stranger = f"{mission}.99.99.1"
        self.waiting_for = f"the verdict on the answer to {stranger}"
        self.answer("not_open", stranger, {"approve": True})
        # (c) the executive's present state (§8b)
        if self.exec_alive and mission not in self.exec_alive:
            self.log.warning("goal mission %s is not among the executives seen %s", mission, sorted(self.exec_alive))
        key = f"{self.root}/exec/{mission}/state"
        self.waiting_for = f"the executive's state on {key}"
        st = self.query(key, None, "exec_state", 5.0)
        self.log.info("state of %s: %s", mission, json.dumps(st))
        self.touch()
        self.report.update(lambda d: d.__setitem__("state", {"key": key, **st}))
        # (d) the right answer
        self.waiting_for = f"the verdict on the right answer to {g.gid}"
        self.answer("right", g.gid, {"approve": True, "comment": "looks good"})
        # (e) the cancel that closes the task
        self.waiting_for = f"the cancel of {g.gid} after the answer"
        if not g.cancel.wait(10.0):
            self.error("no cancel received for %s within 10 s of the verdict", g.gid)
        self.waiting_for = f"the end of mission {mission} (its token {self.root}/alive/exec/{mission} to disappear)"

    def on_record(self, sample):
        """An execution-record line (§8b): the ones about goals and user tasks go to the report."""
        self.touch()
        try:
            line = json.loads(sample.payload.to_bytes())
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            self.error("unreadable record line on %s: %s", sample.key_expr, e)
            return
        if not isinstance(line, dict):
            return
        kind = line.get("kind")
        if kind in ("accepted", "user_task_opened", "user_task_answered", "instance_finished"):
            self.log.info("record: %s", json.dumps(line))
            self.report.update(lambda d: d["record"].append(line))
        if kind == "accepted":
            with self.lock:
                mine = line.get("goal") in self.goals
            if mine:
                self.accepted.set()

    def wind_down(self, g):
        """After an accepted cancel: the wind-down of a user task is immediate (§8a)."""
        self.finish(g, "CANCELED", {})


def main():
    trace_protocol.serve(Station(trace_protocol.arg_parser(__doc__).parse_args()))


if __name__ == "__main__":
    main()
