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
"""

import argparse
import datetime
import json
import logging
import os
import sys
import threading
import time

import zenoh

SERVER = "ground"
STATION = "py-station"
OPERATOR = "py-op"
ACTION = "ground.approve_dig"
IDLE_LIMIT_S = 120.0
ANSWER_TIMEOUT_S = 10.0
MAX_PAYLOAD = 4 * 1024 * 1024
TERMINAL = ("SUCCEEDED", "CANCELED", "ABORTED", "REJECTED")

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
ACTIONS = {a["name"]: a for a in CATALOGUE["actions"]}

log = logging.getLogger(SERVER)


def enc(kind):
    """The encoding of a payload of this protocol (§1a)."""
    return zenoh.Encoding.APPLICATION_JSON.with_schema(f"trace.{kind}/1")


def now_ms():
    return int(time.time() * 1000)


# ---------------------------------------------------------------------------------------------
# Catalogue types (§3)


def check_value(t, v, path):
    """Problems of value `v` against catalogue type `t` (a list of strings, empty if it fits)."""
    if isinstance(t, dict):
        if not isinstance(v, dict):
            return [f"`{path}` must be an object, got {type_name(v)}"]
        return check_object(t, v, path + ".")
    if isinstance(t, list):
        if not isinstance(v, list):
            return [f"`{path}` must be a list, got {type_name(v)}"]
        errs = []
        for i, x in enumerate(v):
            errs += check_value(t[0] if t else "json", x, f"{path}[{i}]")
        return errs
    if not isinstance(t, str):
        return [f"`{path}` has an unreadable catalogue type"]
    if t.endswith("?"):
        if v is None:
            return []
        t = t[:-1]
    if t == "json":
        return []
    if v is None:
        return [f"`{path}` must be {t}, got null"]
    if t.startswith("[") and t.endswith("]"):
        return check_value([t[1:-1]], v, path)
    ok = {
        "int": lambda x: isinstance(x, int) and not isinstance(x, bool) and -(2**63) <= x < 2**63,
        "f64": lambda x: isinstance(x, (int, float)) and not isinstance(x, bool),
        "string": lambda x: isinstance(x, str),
        "bool": lambda x: isinstance(x, bool),
        "timestamp": is_timestamp,
    }.get(t)
    if ok is None:
        return [f"`{path}` has an unknown catalogue type `{t}`"]
    return [] if ok(v) else [f"`{path}` must be {t}, got {type_name(v)}"]


def check_object(schema, obj, prefix=""):
    errs = []
    for k in obj:
        if k not in schema:
            errs.append(f"`{prefix}{k}` is not a field")
    for k, t in schema.items():
        if k in obj:
            errs += check_value(t, obj[k], prefix + k)
        elif not (isinstance(t, str) and (t.endswith("?") or t == "json")):
            errs.append(f"`{prefix}{k}` is missing")
    return errs


def is_timestamp(x):
    if not isinstance(x, str):
        return False
    try:
        datetime.datetime.fromisoformat(x.replace("Z", "+00:00"))
        return True
    except ValueError:
        return False


def type_name(v):
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "a bool"
    if isinstance(v, int):
        return "an int"
    if isinstance(v, float):
        return "a f64"
    if isinstance(v, str):
        return "a string"
    if isinstance(v, list):
        return "a list"
    return "an object"


# ---------------------------------------------------------------------------------------------


class Report:
    """The JSON report, rewritten (atomically) after every notable event."""

    def __init__(self, path, base):
        self.path = path
        self.data = base
        self.lock = threading.Lock()

    def update(self, fn=None):
        with self.lock:
            if fn:
                fn(self.data)
            if not self.path:
                return
            tmp = f"{self.path}.tmp{os.getpid()}"
            try:
                with open(tmp, "w") as f:
                    json.dump(self.data, f, indent=2, default=str)
                os.replace(tmp, self.path)
            except OSError as e:
                log.error("cannot write the report %s: %s", self.path, e)

    def event(self, what, **kw):
        self.update(lambda d: d["events"].append({"t": now_ms(), "what": what, **kw}))


class Goal:
    def __init__(self, gid, action, fields):
        self.gid = gid
        self.action = action
        self.fields = fields
        self.status = None
        self.seq = 0
        self.reason = None
        self.result = None
        self.canceling = False
        self.cancel = threading.Event()


class Station:
    def __init__(self, args):
        self.root = f"{args.key_root}/{args.deployment}"
        self.args = args
        self.lock = threading.Lock()
        self.goals = {}
        self.last_activity = time.monotonic()
        self.waiting_for = f"the executive's liveliness token on {self.root}/alive/exec/*"
        self.exec_alive = set()
        self.exec_seen = False
        self.done = threading.Event()
        self.accepted = threading.Event()
        self.operating = False
        self.report = Report(
            args.report,
            {
                "server": SERVER,
                "deployment": args.deployment,
                "root": self.root,
                "ready": False,
                "station": STATION,
                "operator": OPERATOR,
                "goals": [],
                "user_tasks": [],
                "verdicts": {},
                "state": None,
                "cancels": [],
                "cancel_reason": None,
                "record": [],
                "events": [],
                "errors": [],
                "executives": {"seen": [], "gone": []},
                "exit": None,
            },
        )
        self.session = None
        self.keep = []

    # ---- plumbing

    def touch(self):
        self.last_activity = time.monotonic()

    def error(self, msg, *a):
        text = msg % a if a else msg
        log.warning("%s", text)
        self.report.update(lambda d: d["errors"].append({"t": now_ms(), "error": text}))

    def safe(self, fn):
        """A Zenoh callback that never raises: catch, log, continue."""

        def wrapped(x):
            try:
                fn(x)
            except Exception as e:  # noqa: BLE001 — never crash on a bad message
                log.exception("in %s", fn.__name__)
                self.error("%s failed: %r", fn.__name__, e)

        return wrapped

    def put(self, key, obj, kind, block=True, express=False, raw=None):
        payload = raw if raw is not None else json.dumps(obj)
        self.session.put(
            key,
            payload,
            encoding=enc(kind),
            congestion_control=(zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP),
            express=express,
        )

    def act_key(self, action, what):
        return f"{self.root}/act/{SERVER}/{action}/{what}"

    def parse_key(self, query, kind):
        """(action, goal_id) of a request on `<root>/act/<server>/<action>/<kind>/<goal_id>`,
        or None for a key with wildcards."""
        key = str(query.key_expr)
        if "*" in key or "$" in key:
            return None
        prefix = f"{self.root}/act/{SERVER}/"
        rest = key[len(prefix):].split("/") if key.startswith(prefix) else []
        if len(rest) != 3 or rest[1] != kind:
            raise ValueError(f"unexpected key {key}")
        return rest[0], rest[2]

    @staticmethod
    def payload_json(query, what, key):
        """The request's JSON payload (None when it has none); ValueError naming the problem."""
        p = query.payload
        if p is None:
            return None
        raw = p.to_bytes()
        if len(raw) == 0:
            return None
        if len(raw) > MAX_PAYLOAD:
            raise ValueError(f"malformed {what} payload on {key}: over 4 MiB ({len(raw)} bytes)")
        try:
            return json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise ValueError(f"malformed {what} payload on {key}: {e}") from None

    # ---- goal table

    def transition(self, g, status, text="", result=None):
        """Record a transition (under self.lock) and return the status message to publish."""
        g.status = status
        g.seq += 1
        if result is not None:
            g.result = result
        return {"goal_id": g.gid, "status": status, "seq": g.seq, "text": text}

    def publish_status(self, g, st):
        self.put(self.act_key(g.action, "status"), st, "status")
        log.info("status %s %s seq %d", g.gid, st["status"], st["seq"])
        self.report.event("status", goal_id=g.gid, status=st["status"], seq=st["seq"])
        self.report.update(lambda d: self._goal_report(d, g))

    def _goal_report(self, d, g):
        for r in d["goals"]:
            if r["goal_id"] == g.gid:
                r["status"] = g.status
                r["seq"] = g.seq
                if g.reason:
                    r["reason"] = g.reason
                if g.result is not None:
                    r["result"] = g.result

    def goal_reply(self, g):
        r = {"goal_id": g.gid, "status": g.status}
        if g.status == "REJECTED" and g.reason:
            r["reason"] = g.reason
        if g.status in ("SUCCEEDED", "CANCELED", "ABORTED") and g.result is not None:
            r["result"] = g.result
        return r

    def state_reply(self, g):
        r = {"goal_id": g.gid, "status": g.status, "seq": g.seq}
        if g.status in ("SUCCEEDED", "CANCELED", "ABORTED") and g.result is not None:
            r["result"] = g.result
        return r

    def finish(self, g, status, outputs=None, error=None):
        """Publish the result, then the terminal status; never change a terminal goal."""
        result = {"goal_id": g.gid, "status": status, "outputs": outputs or {}}
        if error:
            result["error"] = error
        with self.lock:
            if g.status in TERMINAL:
                return False
            st = self.transition(g, status, text=(error or {}).get("code", ""), result=result)
        self.put(self.act_key(g.action, "result"), result, "result")
        log.info("result %s %s", g.gid, json.dumps(result))
        self.publish_status(g, st)
        return True

    # ---- queryables

    def on_catalogue(self, query):
        self.touch()
        query.reply(query.key_expr, json.dumps(CATALOGUE), encoding=enc("catalogue"))
        log.debug("catalogue asked on %s", query.key_expr)

    def on_goal(self, query):
        self.touch()
        key = str(query.key_expr)
        try:
            parsed = self.parse_key(query, "goal")
            if parsed is None:
                raise ValueError(f"a goal request needs one goal id, not a wildcard: {key}")
            action, gid = parsed
            if action not in ACTIONS:
                raise ValueError(f"action `{action}` is not served by {SERVER} (key {key})")
            req = self.payload_json(query, "goal", key)
            if not isinstance(req, dict):
                raise ValueError(f"malformed goal payload on {key}: not a JSON object")
            if not isinstance(req.get("goal_id"), str):
                raise ValueError(f"malformed goal payload on {key}: missing field `goal_id`")
            if req["goal_id"] != gid:
                raise ValueError(f"goal id `{req['goal_id']}` differs from the key's `{gid}` ({key})")
            fields = req.get("fields", {})
            if fields is None:
                fields = {}
            if not isinstance(fields, dict):
                raise ValueError(f"malformed goal payload on {key}: `fields` is not an object")
        except ValueError as e:
            self.error("goal refused: %s", e)
            query.reply_err(str(e), encoding=zenoh.Encoding.TEXT_PLAIN)
            return

        start = None
        with self.lock:
            g = self.goals.get(gid)
            if g is not None:
                if g.action != action:
                    msg = f"goal id {gid} is a goal of {g.action}, not {action}"
                    query.reply_err(msg, encoding=zenoh.Encoding.TEXT_PLAIN)
                    self.error("%s", msg)
                    return
                reply = self.goal_reply(g)
                st = None
                log.info("goal %s repeated: %s", gid, g.status)
            else:
                g = Goal(gid, action, fields)
                self.goals[gid] = g
                errs = check_object(ACTIONS[action].get("goal", {}), fields)
                if errs:
                    g.reason = "; ".join(errs)
                    st = self.transition(g, "REJECTED", text=g.reason)
                else:
                    st = self.transition(g, "ACCEPTED")
                    start = g
                reply = self.goal_reply(g)
        if st is not None:
            log.info("goal %s %s %s from %s: %s", gid, action, json.dumps(fields), req.get("client"), g.status)
            self.report.update(
                lambda d: d["goals"].append(
                    {
                        "goal_id": gid,
                        "action": action,
                        "fields": fields,
                        "client": req.get("client"),
                        "decision": g.status,
                        "status": g.status,
                        "seq": g.seq,
                    }
                )
            )
        else:
            self.report.event("goal_repeated", goal_id=gid, status=g.status)
        query.reply(query.key_expr, json.dumps(reply), encoding=enc("goal_reply"))
        if st is not None:
            self.publish_status(g, st)
        if start is not None:
            threading.Thread(target=self.run_activity, args=(start,), daemon=True).start()

    def on_cancel(self, query):
        self.touch()
        key = str(query.key_expr)
        try:
            parsed = self.parse_key(query, "cancel")
            if parsed is None:
                raise ValueError(f"a cancel request needs one goal id, not a wildcard: {key}")
            action, gid = parsed
            if action not in ACTIONS:
                raise ValueError(f"action `{action}` is not served by {SERVER} (key {key})")
            req = self.payload_json(query, "cancel", key)
            if req is not None and not isinstance(req, dict):
                raise ValueError(f"malformed cancel payload on {key}: not a JSON object")
            reason = (req or {}).get("reason")
        except ValueError as e:
            self.error("cancel refused: %s", e)
            query.reply_err(str(e), encoding=zenoh.Encoding.TEXT_PLAIN)
            return
        st = None
        with self.lock:
            g = self.goals.get(gid)
            if g is None or g.action != action:
                answer = "UNKNOWN_GOAL"
            elif g.canceling:  # a repeated cancel gets the same reply, no second wind-down (§4.2)
                answer = "ACCEPTED"
            elif g.status in TERMINAL:
                answer = "TERMINATED"
            else:
                answer = "ACCEPTED"
                g.canceling = True
                st = self.transition(g, "CANCELING")
        log.info("cancel %s (%s): %s", gid, reason, answer)
        self.report.update(
            lambda d: d["cancels"].append({"goal_id": gid, "action": action, "reason": reason, "reply": answer})
        )
        if answer == "ACCEPTED":
            self.report.update(lambda d: d.__setitem__("cancel_reason", reason))
        query.reply(query.key_expr, json.dumps(answer), encoding=enc("cancel_reply"))
        if st is not None:
            self.publish_status(g, st)
            self.close_task(g)
            g.cancel.set()

    def on_state(self, query):
        self.touch()
        key = str(query.key_expr)
        try:
            parsed = self.parse_key(query, "state")
        except ValueError as e:
            self.error("state refused: %s", e)
            query.reply_err(str(e), encoding=zenoh.Encoding.TEXT_PLAIN)
            return
        if parsed is None:  # a wildcard: one reply per known goal, each on its own key
            with self.lock:
                replies = [(self.act_key(g.action, f"state/{g.gid}"), self.state_reply(g)) for g in self.goals.values()]
            n = 0
            for k, r in replies:
                if query.key_expr.intersects(zenoh.KeyExpr(k)):
                    query.reply(k, json.dumps(r), encoding=enc("state_reply"))
                    n += 1
            log.info("state %s: %d goals", key, n)
            return
        action, gid = parsed
        if action not in ACTIONS:
            msg = f"action `{action}` is not served by {SERVER} (key {key})"
            self.error("state refused: %s", msg)
            query.reply_err(msg, encoding=zenoh.Encoding.TEXT_PLAIN)
            return
        with self.lock:
            g = self.goals.get(gid)
            r = self.state_reply(g) if g and g.action == action else {"goal_id": gid, "status": "UNKNOWN", "seq": 0}
        log.info("state %s: %s", gid, r["status"])
        self.report.event("state_asked", goal_id=gid, status=r["status"])
        query.reply(query.key_expr, json.dumps(r), encoding=enc("state_reply"))

    def on_exec_liveliness(self, sample):
        self.touch()
        mission = str(sample.key_expr).rsplit("/", 1)[-1]
        if sample.kind == zenoh.SampleKind.PUT:
            self.exec_alive.add(mission)
            self.exec_seen = True
            self.waiting_for = (
                f"the end of mission {mission}: goals or its token {self.root}/alive/exec/{mission} to disappear"
            )
            log.info("executive %s is up", mission)
            self.report.update(lambda d: d["executives"]["seen"].append(mission))
        else:
            self.exec_alive.discard(mission)
            log.info("executive %s is gone", mission)
            self.report.update(lambda d: d["executives"]["gone"].append(mission))
            if self.exec_seen and not self.exec_alive:
                self.done.set()

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
            log.exception("operator on %s", g.gid)
            self.error("operator on %s failed: %r", g.gid, e)

    def answer_key(self, gid):
        return f"{self.root}/act/{SERVER}/{ACTION}/answer/{gid}"

    def answer(self, label, gid, fields):
        """Send an answer query (§8a) and record the verdict."""
        key = self.answer_key(gid)
        payload = {"goal_id": gid, "fields": fields, "operator": OPERATOR, "station": STATION}
        log.info("answer %s on %s: %s", label, key, json.dumps(fields))
        verdict = self.query(key, payload, "answer", ANSWER_TIMEOUT_S)
        log.info("verdict %s: %s", label, json.dumps(verdict))
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
            log.warning("goal mission %s is not among the executives seen %s", mission, sorted(self.exec_alive))
        key = f"{self.root}/exec/{mission}/state"
        self.waiting_for = f"the executive's state on {key}"
        st = self.query(key, None, "exec_state", 5.0)
        log.info("state of %s: %s", mission, json.dumps(st))
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
            log.info("record: %s", json.dumps(line))
            self.report.update(lambda d: d["record"].append(line))
        if kind == "accepted":
            with self.lock:
                mine = line.get("goal") in self.goals
            if mine:
                self.accepted.set()

    def close_task(self, g):
        """After an accepted cancel: the wind-down of a user task is immediate."""
        self.finish(g, "CANCELED", {})

    # ---- main

    def run(self):
        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("connect/endpoints", json.dumps([self.args.connect]))
        self.session = zenoh.open(conf)
        s = self.session
        base = f"{self.root}/act/{SERVER}"
        self.keep += [
            s.declare_subscriber(f"{self.root}/exec/*/record", self.safe(self.on_record)),
            s.declare_queryable(f"{base}/*/goal/*", self.safe(self.on_goal), complete=True),
            s.declare_queryable(f"{base}/*/cancel/*", self.safe(self.on_cancel), complete=True),
            s.declare_queryable(f"{base}/*/state/*", self.safe(self.on_state), complete=True),
            s.declare_queryable(f"{self.root}/cat/{SERVER}", self.safe(self.on_catalogue)),
        ]
        self.keep.append(
            s.liveliness().declare_subscriber(f"{self.root}/alive/exec/*", self.safe(self.on_exec_liveliness),
                                              history=True)
        )
        self.keep.append(s.liveliness().declare_token(f"{self.root}/alive/{SERVER}/{STATION}"))
        for a in ACTIONS:  # the token says the action is served: last
            self.keep.append(s.liveliness().declare_token(f"{self.root}/alive/act/{SERVER}/{a}/{STATION}"))
        self.report.update(lambda d: d.__setitem__("ready", True))
        print(f"ready {SERVER} {STATION} — deployment {self.args.deployment} (keys {self.root}/…)", flush=True)
        log.info("station %s serving %s on %s, connected to %s", STATION, ", ".join(ACTIONS), self.root,
                 self.args.connect)

        code = 0
        while True:
            if self.done.wait(0.5):
                log.info("the executive is gone: the mission ended")
                self.report.update(lambda d: d.__setitem__("exit", {"code": 0, "why": "executive gone"}))
                break
            idle = time.monotonic() - self.last_activity
            if idle > IDLE_LIMIT_S:
                msg = f"nothing happened for {IDLE_LIMIT_S:.0f} s while waiting for {self.waiting_for}"
                log.error("%s", msg)
                print(f"{SERVER} {STATION}: {msg}", file=sys.stderr, flush=True)
                self.report.update(lambda d: d.__setitem__("exit", {"code": 2, "why": msg}))
                code = 2
                break
        self.done.set()
        try:
            for k in self.keep:
                k.undeclare()
            s.close()
        except Exception as e:  # noqa: BLE001
            log.warning("closing: %r", e)
        return code


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--connect", "-e", default="tcp/127.0.0.1:7447", help="Zenoh endpoint to connect to")
    p.add_argument("--deployment", default=os.environ.get("TRACE_DEPLOYMENT", "default"))
    p.add_argument("--key-root", default="trace")
    p.add_argument("--report", default=None, help="JSON report file, rewritten after every notable event")
    args = p.parse_args()
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format=f"%(asctime)s {SERVER} {STATION} %(levelname)s %(message)s")
    sys.exit(Station(args).run())


if __name__ == "__main__":
    main()
