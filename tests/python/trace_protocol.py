"""What every TRACE server needs, whatever it serves, written from docs/protocol.md alone.

Shared by `trace_system.py` (a system) and `trace_ground.py` (a ground station): payload
encodings (§1a), catalogue type checks (§3), the JSON report, the goal table with the goal,
cancel and state queryables (§4), statuses and results (§5.1, §5.3), liveliness (§6), the
executive's token that ends the run (§8b), and the idle bound, argument parsing and logging.

A script subclasses `Server`, gives it its catalogue, and implements `run_activity`; the
hooks `declare`, `started`, `cancel_answered` and `wind_down` are where the two differ.
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

IDLE_LIMIT_S = 120.0
"""Exit with code 2 when nothing happens for this long (every wait has an end, §4.4)."""

MAX_PAYLOAD = 4 * 1024 * 1024
"""The largest payload of this protocol (§1a)."""

TERMINAL = ("SUCCEEDED", "CANCELED", "ABORTED", "REJECTED")
"""The terminal statuses (§9): a goal in one of them never changes again."""

WITH_RESULT = ("SUCCEEDED", "CANCELED", "ABORTED")
"""The statuses whose goal and state replies carry the result (§4.1, §4.3)."""


def enc(kind):
    """The encoding of a payload of this protocol (§1a)."""
    return zenoh.Encoding.APPLICATION_JSON.with_schema(f"trace.{kind}/1")


def now_ms():
    """Wall time in ms since the epoch (a system without a mission clock, §7)."""
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
    """Problems of object `obj` against a catalogue object type: unknown fields, missing
    required ones (not `T?`, not `json`), and each field's own type."""
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
    """Whether `x` is a catalogue `timestamp`: an ISO 8601 / RFC 3339 string."""
    if not isinstance(x, str):
        return False
    try:
        datetime.datetime.fromisoformat(x.replace("Z", "+00:00"))
        return True
    except ValueError:
        return False


def type_name(v):
    """The catalogue name of a JSON value's type, for problem texts ("got a string")."""
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

    def __init__(self, path, base, log):
        self.path = path
        self.data = base
        self.log = log
        self.lock = threading.Lock()

    def update(self, fn=None):
        """Apply `fn` to the report's data (if given), then rewrite the file."""
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
                self.log.error("cannot write the report %s: %s", self.path, e)

    def event(self, what, **kw):
        """Append a timestamped event to the report's `events`."""
        self.update(lambda d: d["events"].append({"t": now_ms(), "what": what, **kw}))


class Goal:
    """One row of the goal table (§11.2): one activity run, identified by its goal id (§1)."""

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


class Server:
    """A TRACE server over Zenoh (§2, §11): serves its catalogue, keeps an idempotent goal
    table behind the goal, cancel and state queryables, publishes statuses and results, and
    runs until the executive's token has come and gone (exit 0) or nothing happens for
    IDLE_LIMIT_S (exit 2).

    `name` says who this is in the `ready` line, the log and the idle message; `instance` is
    the last chunk of the process token `<root>/alive/<server>/<instance>` (§6);
    `report_fields` are the script's own report fields (with their starting values).
    """

    def __init__(self, args, catalogue, name, instance, report_fields):
        self.args = args
        self.catalogue = catalogue
        self.server = catalogue["server"]
        self.actions = {a["name"]: a for a in catalogue["actions"]}
        self.name = name
        self.instance = instance
        self.log = logging.getLogger(self.server)
        self.root = f"{args.key_root}/{args.deployment}"
        self.lock = threading.Lock()
        self.goals = {}
        self.last_activity = time.monotonic()
        self.waiting_for = f"the executive's liveliness token on {self.root}/alive/exec/*"
        self.exec_alive = set()
        self.exec_seen = False
        self.done = threading.Event()
        self.report = Report(
            args.report,
            {
                "server": self.server,
                "deployment": args.deployment,
                "root": self.root,
                "ready": False,
                **report_fields,
                "goals": [],
                "cancels": [],
                "events": [],
                "errors": [],
                "executives": {"seen": [], "gone": []},
                "exit": None,
            },
            self.log,
        )
        self.session = None
        self.keep = []

    # ---- what a script defines

    def run_activity(self, g):
        """Run goal `g` once it was ACCEPTED and the status published (in its own thread)."""
        raise NotImplementedError

    def declare(self, session):
        """The script's own declarations, made before the queryables (a list to keep)."""
        return []

    def started(self):
        """Called once every token is declared, just before the `ready` line."""

    def cancel_answered(self, gid, reason, answer):
        """Called when a cancel request gets `answer` (§4.2), before the reply is sent."""

    def wind_down(self, g):
        """Called when `g` has gone CANCELING (the status published), before its `cancel`
        event is set; the activity sees the event and publishes its own ending."""

    def ignores(self, gid):
        """Whether requests about goal `gid` go unanswered (a server gone silent)."""
        return False

    def action_token(self, action):
        """The liveliness token that says `action` is served (§6)."""
        return f"{self.root}/alive/act/{self.server}/{action}"

    def serving_line(self):
        """What the log says once the server serves."""
        return f"serving {', '.join(self.actions)} on {self.root}, connected to {self.args.connect}"

    # ---- plumbing

    def touch(self):
        """Something happened: the idle bound starts again."""
        self.last_activity = time.monotonic()

    def error(self, msg, *a):
        """Log a problem at warn and record it in the report's `errors`."""
        text = msg % a if a else msg
        self.log.warning("%s", text)
        self.report.update(lambda d: d["errors"].append({"t": now_ms(), "error": text}))

    def safe(self, fn):
        """A Zenoh callback that never raises: catch, log, continue."""

        def wrapped(x):
            try:
                fn(x)
            except Exception as e:  # noqa: BLE001 — never crash on a bad message
                self.log.exception("in %s", fn.__name__)
                self.error("%s failed: %r", fn.__name__, e)

        return wrapped

    def put(self, key, obj, kind, block=True, express=False, raw=None):
        """Publish `obj` as JSON (or the bytes `raw`) with the encoding of `kind` (§1a);
        congestion control Block unless `block` is false (§2)."""
        payload = raw if raw is not None else json.dumps(obj)
        self.session.put(
            key,
            payload,
            encoding=enc(kind),
            congestion_control=(zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP),
            express=express,
        )

    def act_key(self, action, what):
        """`<root>/act/<server>/<action>/<what>` (§2)."""
        return f"{self.root}/act/{self.server}/{action}/{what}"

    def parse_key(self, query, kind):
        """(action, goal_id) of a request on `<root>/act/<server>/<action>/<kind>/<goal_id>`,
        or None for a key with wildcards."""
        key = str(query.key_expr)
        if "*" in key or "$" in key:
            return None
        prefix = f"{self.root}/act/{self.server}/"
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

    def one_goal_request(self, query, kind):
        """(key, action, goal_id, payload) of a `goal` or `cancel` request, which must name one
        goal of a served action and carry a JSON object or nothing (payload None);
        ValueError naming the problem otherwise (§4)."""
        key = str(query.key_expr)
        parsed = self.parse_key(query, kind)
        if parsed is None:
            raise ValueError(f"a {kind} request needs one goal id, not a wildcard: {key}")
        action, gid = parsed
        if action not in self.actions:
            raise ValueError(f"action `{action}` is not served by {self.server} (key {key})")
        req = self.payload_json(query, kind, key)
        if req is not None and not isinstance(req, dict):
            raise ValueError(f"malformed {kind} payload on {key}: not a JSON object")
        return key, action, gid, req

    def refuse(self, query, what, msg):
        """Answer a request that is not one this server can answer with `reply_err` (§1a)."""
        self.error("%s refused: %s", what, msg)
        query.reply_err(str(msg), encoding=zenoh.Encoding.TEXT_PLAIN)

    # ---- goal table (§4, §5)

    def transition(self, g, status, text="", result=None):
        """Record a transition (under self.lock) and return the status message to publish
        (§5.1: `seq` counts the goal's transitions from 1)."""
        g.status = status
        g.seq += 1
        if result is not None:
            g.result = result
        return {"goal_id": g.gid, "status": status, "seq": g.seq, "text": text}

    def publish_status(self, g, st):
        """Publish a status message (§5.1) and record it in the report."""
        self.put(self.act_key(g.action, "status"), st, "status")
        self.log.info("status %s %s seq %d", g.gid, st["status"], st["seq"])
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
        """The goal reply (§4.1): the goal's current status, its reason or its result."""
        r = {"goal_id": g.gid, "status": g.status}
        if g.status == "REJECTED" and g.reason:
            r["reason"] = g.reason
        if g.status in WITH_RESULT and g.result is not None:
            r["result"] = g.result
        return r

    def state_reply(self, g):
        """The state reply (§4.3) of a known goal."""
        r = {"goal_id": g.gid, "status": g.status, "seq": g.seq}
        if g.status in WITH_RESULT and g.result is not None:
            r["result"] = g.result
        return r

    def finish(self, g, status, outputs=None, error=None):
        """Publish the result (§5.3), then the terminal status; never change a terminal goal."""
        result = {"goal_id": g.gid, "status": status, "outputs": outputs or {}}
        if error:
            result["error"] = error
        with self.lock:
            if g.status in TERMINAL:
                return False
            st = self.transition(g, status, text=(error or {}).get("code", ""), result=result)
        self.put(self.act_key(g.action, "result"), result, "result")
        self.log.info("result %s %s", g.gid, json.dumps(result))
        self.publish_status(g, st)
        return True

    # ---- queryables

    def on_catalogue(self, query):
        """`<root>/cat/<server>`: the catalogue (§3)."""
        self.touch()
        query.reply(query.key_expr, json.dumps(self.catalogue), encoding=enc("catalogue"))
        self.log.debug("catalogue asked on %s", query.key_expr)

    def on_goal(self, query):
        """`…/<action>/goal/<goal_id>` (§4.1): idempotent per goal id; the first request is
        type-checked against the catalogue and decides; an accepted goal runs `run_activity`."""
        self.touch()
        try:
            key, action, gid, req = self.one_goal_request(query, "goal")
            if req is None:
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
            self.refuse(query, "goal", e)
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
                self.log.info("goal %s repeated: %s", gid, g.status)
            else:
                g = Goal(gid, action, fields)
                self.goals[gid] = g
                errs = check_object(self.actions[action].get("goal", {}), fields)
                if errs:
                    g.reason = "; ".join(errs)
                    st = self.transition(g, "REJECTED", text=g.reason)
                else:
                    st = self.transition(g, "ACCEPTED")
                    start = g
                reply = self.goal_reply(g)
        if st is not None:
            self.log.info("goal %s %s %s from %s: %s", gid, action, json.dumps(fields), req.get("client"), g.status)
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
        """`…/<action>/cancel/<goal_id>` (§4.2): `"ACCEPTED"` (then CANCELING, once),
        `"UNKNOWN_GOAL"` or `"TERMINATED"`."""
        self.touch()
        try:
            _, action, gid, req = self.one_goal_request(query, "cancel")
            reason = (req or {}).get("reason")
        except ValueError as e:
            self.refuse(query, "cancel", e)
            return
        if self.ignores(gid):
            self.log.info("cancel %s (%s): not answered (silent)", gid, reason)
            self.report.event("cancel_ignored", goal_id=gid)
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
        self.log.info("cancel %s (%s): %s", gid, reason, answer)
        self.report.update(
            lambda d: d["cancels"].append({"goal_id": gid, "action": action, "reason": reason, "reply": answer})
        )
        self.cancel_answered(gid, reason, answer)
        query.reply(query.key_expr, json.dumps(answer), encoding=enc("cancel_reply"))
        if st is not None:
            self.publish_status(g, st)
            self.wind_down(g)
            g.cancel.set()

    def on_state(self, query):
        """`…/<action>/state/<goal_id>` (§4.3): never blocks; a wildcard gets one reply per
        known goal, each on its own key."""
        self.touch()
        key = str(query.key_expr)
        try:
            parsed = self.parse_key(query, "state")
        except ValueError as e:
            self.refuse(query, "state", e)
            return
        if parsed is None:  # a wildcard: one reply per known goal, each on its own key
            with self.lock:
                replies = [(self.act_key(g.action, f"state/{g.gid}"), self.state_reply(g)) for g in self.goals.values()]
            n = 0
            for k, r in replies:
                if query.key_expr.intersects(zenoh.KeyExpr(k)):
                    query.reply(k, json.dumps(r), encoding=enc("state_reply"))
                    n += 1
            self.log.info("state %s: %d goals", key, n)
            return
        action, gid = parsed
        if self.ignores(gid):
            self.log.info("state %s: not answered (silent)", gid)
            self.report.event("state_ignored", goal_id=gid)
            return
        if action not in self.actions:
            self.refuse(query, "state", f"action `{action}` is not served by {self.server} (key {key})")
            return
        with self.lock:
            g = self.goals.get(gid)
            r = self.state_reply(g) if g and g.action == action else {"goal_id": gid, "status": "UNKNOWN", "seq": 0}
        self.log.info("state %s: %s", gid, r["status"])
        self.report.event("state_asked", goal_id=gid, status=r["status"])
        query.reply(query.key_expr, json.dumps(r), encoding=enc("state_reply"))

    def on_exec_liveliness(self, sample):
        """The executive's token `<root>/alive/exec/<mission>` (§8b): once every executive
        seen is gone, the mission has ended and the server stops."""
        self.touch()
        mission = str(sample.key_expr).rsplit("/", 1)[-1]
        if sample.kind == zenoh.SampleKind.PUT:
            self.exec_alive.add(mission)
            self.exec_seen = True
            self.waiting_for = (
                f"the end of mission {mission}: goals or its token {self.root}/alive/exec/{mission} to disappear"
            )
            self.log.info("executive %s is up", mission)
            self.report.update(lambda d: d["executives"]["seen"].append(mission))
        else:
            self.exec_alive.discard(mission)
            self.log.info("executive %s is gone", mission)
            self.report.update(lambda d: d["executives"]["gone"].append(mission))
            if self.exec_seen and not self.exec_alive:
                self.done.set()

    # ---- main

    def run(self):
        """Open the session (§1a), declare what §11 says in its order (the action tokens
        last), print the `ready` line, and wait for the end; returns the exit code."""
        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("connect/endpoints", json.dumps([self.args.connect]))
        self.session = zenoh.open(conf)
        s = self.session
        base = f"{self.root}/act/{self.server}"
        self.keep += self.declare(s)
        self.keep += [
            s.declare_queryable(f"{base}/*/goal/*", self.safe(self.on_goal), complete=True),
            s.declare_queryable(f"{base}/*/cancel/*", self.safe(self.on_cancel), complete=True),
            s.declare_queryable(f"{base}/*/state/*", self.safe(self.on_state), complete=True),
            s.declare_queryable(f"{self.root}/cat/{self.server}", self.safe(self.on_catalogue)),
        ]
        self.keep.append(
            s.liveliness().declare_subscriber(f"{self.root}/alive/exec/*", self.safe(self.on_exec_liveliness),
                                              history=True)
        )
        self.keep.append(s.liveliness().declare_token(f"{self.root}/alive/{self.server}/{self.instance}"))
        for a in self.actions:  # the token says the action is served: last
            self.keep.append(s.liveliness().declare_token(self.action_token(a)))
        self.started()
        self.report.update(lambda d: d.__setitem__("ready", True))
        print(f"ready {self.name} — deployment {self.args.deployment} (keys {self.root}/…)", flush=True)
        self.log.info("%s", self.serving_line())

        code = 0
        while True:
            if self.done.wait(0.5):
                self.log.info("the executive is gone: the mission ended")
                self.report.update(lambda d: d.__setitem__("exit", {"code": 0, "why": "executive gone"}))
                break
            idle = time.monotonic() - self.last_activity
            if idle > IDLE_LIMIT_S:
                msg = f"nothing happened for {IDLE_LIMIT_S:.0f} s while waiting for {self.waiting_for}"
                self.log.error("%s", msg)
                print(f"{self.name}: {msg}", file=sys.stderr, flush=True)
                self.report.update(lambda d: d.__setitem__("exit", {"code": 2, "why": msg}))
                code = 2
                break
        self.done.set()
        try:
            for k in self.keep:
                k.undeclare()
            s.close()
        except Exception as e:  # noqa: BLE001
            self.log.warning("closing: %r", e)
        return code


def arg_parser(doc):
    """The command line every server takes (described by the first paragraph of `doc`):
    `--connect`, `--deployment` (§1), `--key-root`, `--report`."""
    p = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    p.add_argument("--connect", "-e", default="tcp/127.0.0.1:7447", help="Zenoh endpoint to connect to")
    p.add_argument("--deployment", default=os.environ.get("TRACE_DEPLOYMENT", "default"))
    p.add_argument("--key-root", default="trace")
    p.add_argument("--report", default=None, help="JSON report file, rewritten after every notable event")
    return p


def serve(server):
    """Log on stderr as `server.name`, run the server and exit with its code."""
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format=f"%(asctime)s {server.name} %(levelname)s %(message)s")
    sys.exit(server.run())
