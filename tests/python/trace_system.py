#!/usr/bin/env python3
"""A TRACE system (server) `py_lander`, written from docs/protocol.md alone.

Serves `drill.dig`, `thermal.heat`, `thermal.cool`, `probe.scan` and `arm.stow` over Zenoh
(protocol version 1):
catalogue, goal/cancel/state queryables with an idempotent goal table, liveliness tokens,
statuses, feedback, results and `battery_soc_pct` telemetry. On purpose it also sends messages
the executive must refuse (mistyped feedback and telemetry, a non-JSON result, a result for a
goal nobody sent), so a test can check they are refused.

    trace_system.py --connect tcp/127.0.0.1:7447 --deployment D [--key-root trace] --report FILE

Prints `ready py_lander — deployment D (keys trace/D/…)` on stdout when it serves; logs on
stderr; writes a JSON report to --report after every notable event. Exits 0 once the
executive's token (`<root>/alive/exec/<mission>`) has been seen and has disappeared, 2 when
nothing happens for 120 s.

The server machinery (goal table, queryables, statuses, liveliness, report) is
trace_protocol.py's; this file holds the catalogue and the activities.
"""

import os
import threading

import trace_protocol
from trace_protocol import now_ms

SERVER = "py_lander"

CATALOGUE = {
    "server": SERVER,
    "actions": [
        {
            "name": "drill.dig",
            "description": "Dig with the drill to the asked depth",
            "goal": {"depth_cm": "f64"},
            "result": {"achieved_cm": "f64"},
            "feedback": {"depth_cm": "f64"},
            "errors": {"TOOL_STUCK": "the drill tool is stuck"},
        },
        {
            "name": "thermal.heat",
            "description": "Heat the instrument bay",
            "goal": {},
            "result": {},
            "feedback": {},
            "errors": {"HEATER_FAULT": "the heater does not respond"},
        },
        {
            "name": "thermal.cool",
            "description": "Let the instrument bay cool down",
            "goal": {},
            "result": {},
            "feedback": {},
            "errors": {},
        },
        {
            "name": "probe.scan",
            "description": "Scan with the probe (with --silent: accept, then say nothing more)",
            "goal": {},
            "result": {},
            "feedback": {},
            "errors": {},
            "cost": {"duration_s": 1.0, "power_w": 0.0},
        },
        {
            "name": "arm.stow",
            "description": "Stow the arm",
            "goal": {},
            "result": {},
            "feedback": {},
            "errors": {},
        },
    ],
    "telemetry": {"battery_soc_pct": "f64"},
}


class System(trace_protocol.Server):
    """The lander: runs each accepted goal as a scripted activity (`do_<action>`) and publishes
    `battery_soc_pct` every 200 ms."""

    def __init__(self, args):
        super().__init__(
            args,
            CATALOGUE,
            name=SERVER,
            instance=f"py-{os.getpid()}",
            report_fields={"telemetry_sent": 0, "bad_telemetry_sent": False},
        )
        self.bad_tm_sent = False
        self.silent = set()

    def ignores(self, gid):
        """With --silent, a `probe.scan` goal, once accepted, gets no status, result, state or
        cancel reply: the system stays connected and says nothing (the executive's watchdog)."""
        return gid in self.silent

    def started(self):
        """Telemetry starts once the tokens are declared (§7)."""
        threading.Thread(target=self.telemetry_loop, daemon=True).start()

    # ---- activities

    def step(self, g, pause=0.2):
        """Pause; True if the goal was asked to cancel meanwhile."""
        return g.cancel.wait(pause)

    def executing(self, g):
        """ACCEPTED → EXECUTING (§5.1); False if the goal left ACCEPTED meanwhile."""
        with self.lock:
            if g.status != "ACCEPTED":
                return False
            st = self.transition(g, "EXECUTING")
        self.publish_status(g, st)
        return True

    def run_activity(self, g):
        """A short pause, EXECUTING, then the action's `do_<action>`; ABORTED if it fails."""
        try:
            if self.step(g) or not self.executing(g):
                self.finish(g, "CANCELED")
                return
            getattr(self, "do_" + g.action.replace(".", "_"))(g)
        except Exception as e:  # noqa: BLE001
            self.log.exception("activity %s", g.gid)
            self.error("activity %s failed: %r", g.gid, e)
            self.finish(g, "ABORTED", error={"code": "ABORTED", "message": f"internal error: {e!r}"})

    def do_drill_dig(self, g):
        fb_key = self.act_key(g.action, "feedback")
        if self.step(g):
            return self.finish(g, "CANCELED", {"achieved_cm": 0.0})
        self.put(fb_key, {"goal_id": g.gid, "progress_pct": 50.0, "fields": {"depth_cm": 2.5}}, "feedback",
                 block=False, express=True)
        self.report.event("feedback", goal_id=g.gid, fields={"depth_cm": 2.5}, valid=True)
        self.send_bad_telemetry()
        # Wrong messages the executive must refuse (§4.4 "dropped, logged, counted").
        if self.step(g):
            return self.finish(g, "CANCELED", {"achieved_cm": 2.5})
        self.put(fb_key, {"goal_id": g.gid, "progress_pct": 60.0, "fields": {"depth_cm": "deep"}}, "feedback",
                 block=False, express=True)
        self.report.event("bad_feedback", goal_id=g.gid, fields={"depth_cm": "deep"})
        if self.step(g):
            return self.finish(g, "CANCELED", {"achieved_cm": 2.5})
        self.put(self.act_key(g.action, "result"), None, "result", raw=b"this is not JSON {")
        self.report.event("garbage_result", goal_id=g.gid)
        if self.step(g):
            return self.finish(g, "CANCELED", {"achieved_cm": 2.5})
        mission = g.gid.rsplit(".", 3)[0]
        stranger = {"mission": f"{mission}.99.99.1", "other": "other-mission.99.99.1"}.get(self.args.stranger)
        if stranger is None:
            self.log.info("not sending the result for a goal nobody sent (--stranger none)")
            return self.finish(g, "SUCCEEDED", {"achieved_cm": 5.2})
        self.put(self.act_key(g.action, "result"),
                 {"goal_id": stranger, "status": "SUCCEEDED", "outputs": {"achieved_cm": 1.0}}, "result")
        self.report.event("stranger_result", goal_id=stranger)
        if self.step(g):
            return self.finish(g, "CANCELED", {"achieved_cm": 2.5})
        self.finish(g, "SUCCEEDED", {"achieved_cm": 5.2})

    def do_thermal_heat(self, g):
        if self.step(g, 0.3):
            return self.finish(g, "CANCELED")
        self.finish(g, "ABORTED", error={"code": "HEATER_FAULT", "message": "heater element open circuit"})

    def do_thermal_cool(self, g):
        if self.step(g, 0.3):
            return self.finish(g, "CANCELED")
        self.finish(g, "SUCCEEDED", {})

    def do_probe_scan(self, g):
        if self.args.silent:
            self.silent.add(g.gid)
            self.log.info("goal %s accepted; silent from now on", g.gid)
            return
        if self.step(g, 0.3):
            return self.finish(g, "CANCELED")
        self.finish(g, "SUCCEEDED", {})

    def do_arm_stow(self, g):
        if self.step(g, 0.3):
            return self.finish(g, "CANCELED")
        self.finish(g, "SUCCEEDED", {})

    # ---- telemetry (§7)

    def tm_key(self):
        """The telemetry channel `<root>/tm/<server>/power` (§7)."""
        return f"{self.root}/tm/{SERVER}/power"

    def send_bad_telemetry(self):
        """Once: a mistyped `battery_soc_pct` the executive must drop (`mistyped`, §7)."""
        if self.bad_tm_sent:
            return
        self.bad_tm_sent = True
        self.put(self.tm_key(), {"mission_ms": now_ms(), "values": {"battery_soc_pct": "high"}}, "telemetry",
                 block=False)
        self.log.info("sent the mistyped telemetry battery_soc_pct = \"high\"")
        self.report.update(lambda d: d.__setitem__("bad_telemetry_sent", True))

    def telemetry_loop(self):
        """`battery_soc_pct` every 200 ms, slowly draining, until the server stops."""
        soc = 92.0
        n = 0
        while not self.done.is_set():
            try:
                self.put(self.tm_key(), {"mission_ms": now_ms(), "values": {"battery_soc_pct": round(soc, 2)}},
                         "telemetry", block=False)
                n += 1
                soc = max(20.0, soc - 0.05)
                if n % 25 == 1:
                    self.report.update(lambda d: d.__setitem__("telemetry_sent", n))
            except Exception as e:  # noqa: BLE001
                self.log.warning("telemetry: %r", e)
            self.done.wait(0.2)
        self.report.update(lambda d: d.__setitem__("telemetry_sent", n))


def main():
    p = trace_protocol.arg_parser(__doc__)
    p.add_argument("--stranger", choices=("mission", "other", "none"), default="mission",
                   help="the goal id of the well-formed result for a goal nobody sent, published during drill.dig: "
                        "`<mission>.99.99.1` (default), `other-mission.99.99.1`, or none (to isolate executive issues)")
    p.add_argument("--silent", action="store_true",
                   help="accept `probe.scan` goals, then answer nothing about them (no status, result, state or cancel reply)")
    trace_protocol.serve(System(p.parse_args()))


if __name__ == "__main__":
    main()
