"""TRACE's bridge to ROS 2 actions (connectors/ros2): one rclpy node, driven over this process's
stdin and stdout, one JSON object per line.

    bridge.py client NODE NAMESPACE    the connector's action clients (connector.rs)
    bridge.py server NODE NAMESPACE    action servers of a Rust system (server.rs)

Client commands (stdin):
  {"op": "goal", "goal_id": ID, "uuid": HEX32, "action": "/fibonacci",
   "type": "test_msgs/action/Fibonacci", "fields": {...}}
  {"op": "resume", ...the same}: a goal sent before a restart: its result by its UUID
  {"op": "cancel", "goal_id": ID}
  {"op": "watch", "action": NAME, "type": TYPE}: say when the server appears and goes
Events (stdout):
  {"ev": "ready"}
  {"ev": "accepted" | "rejected", "goal_id": ID, "reason": ...}
  {"ev": "feedback", "goal_id": ID, "fields": {...}}
  {"ev": "result", "goal_id": ID, "status": "SUCCEEDED" | "ABORTED" | "CANCELED" | "UNKNOWN",
   "fields": {...}}
  {"ev": "server", "action": NAME, "up": true | false}
  {"ev": "error", "goal_id": ID, "reason": ...}: the goal could not be sent

Server commands (stdin):
  {"op": "serve", "resource": R, "action": "arm/stow", "type": "europa_msgs/action/Stow"}
  {"op": "feedback", "uuid": HEX32, "fields": {...}}
  {"op": "succeed" | "abort" | "canceled", "uuid": HEX32, "fields": {...}}: the goal's result
Server events (stdout):
  {"ev": "ready"}
  {"ev": "serving", "resource": R} | {"ev": "unserved", "resource": R, "reason": ...}
  {"ev": "goal", "uuid": HEX32, "resource": R, "fields": {...}}: a goal accepted, to execute
  {"ev": "cancel", "uuid": HEX32}: its client asks to cancel it
  {"ev": "error", "uuid": HEX32 | null, "reason": ...}

The goal's UUID is the connector's (derived from TRACE's goal id), so a goal sent again after a
restart is the same goal to the server, which refuses a UUID it already holds.
"""

import array
import importlib
import json
import sys
import threading
import uuid as uuidlib

import rclpy
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient, ActionServer, CancelResponse
from rclpy.action.client import ClientGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from unique_identifier_msgs.msg import UUID

OUT = threading.Lock()

STATUS = {
    GoalStatus.STATUS_SUCCEEDED: "SUCCEEDED",
    GoalStatus.STATUS_ABORTED: "ABORTED",
    GoalStatus.STATUS_CANCELED: "CANCELED",
    GoalStatus.STATUS_UNKNOWN: "UNKNOWN",
}


def say(event):
    with OUT:
        sys.stdout.write(json.dumps(event) + "\n")
        sys.stdout.flush()


def action_type(name):
    pkg, _, cls = name.split("/")
    return getattr(importlib.import_module(f"{pkg}.action"), cls)


def to_ros(msg, fields, path=""):
    """Sets a message's fields from JSON; rclpy's setters check each type and range."""
    slots = dict(zip(msg.get_fields_and_field_types().keys(), msg.SLOT_TYPES))
    for key, value in fields.items():
        where = f"{path}{key}"
        if key not in slots:
            raise ValueError(f"`{where}` is not a field")
        current = getattr(msg, key)
        if isinstance(value, dict):
            to_ros(current, value, where + ".")
        elif isinstance(value, list) and hasattr(slots[key], "value_type") and hasattr(
            slots[key].value_type, "namespaces"
        ):
            t = slots[key].value_type
            cls = getattr(importlib.import_module(".".join(t.namespaces)), t.name)
            items = []
            for i, item in enumerate(value):
                m = cls()
                to_ros(m, item, f"{where}[{i}].")
                items.append(m)
            setattr(msg, key, items)
        else:
            value = widen(slots[key], value)
            try:
                setattr(msg, key, value)
            except (AssertionError, TypeError, ValueError) as e:
                raise ValueError(f"`{where}`: {e}") from e
    return msg


FLOATS = ("float", "double", "long double")


def widen(slot, value):
    """A whole number for a floating-point field (or sequence of them) is that number: JSON,
    FEEL and CEL do not tell `10` from `10.0`, and rclpy's setters refuse an int there."""
    inner = getattr(slot, "value_type", slot)
    if getattr(inner, "typename", None) not in FLOATS:
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, list):
        return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in value]
    return value


def to_json(value):
    if hasattr(value, "get_fields_and_field_types"):
        return {k: to_json(getattr(value, k)) for k in value.get_fields_and_field_types()}
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if isinstance(value, (list, tuple, array.array)) or type(value).__name__ == "ndarray":
        return [to_json(v) for v in value]
    if hasattr(value, "item"):  # a numpy scalar
        return value.item()
    return value


class Bridge:
    def __init__(self, node):
        self.node = node
        self.clients = {}
        self.handles = {}
        self.lock = threading.Lock()

    def client(self, action, type_name):
        with self.lock:
            c = self.clients.get(action)
            if c is None:
                c = ActionClient(self.node, action_type(type_name), action)
                self.clients[action] = c
            return c

    def goal(self, cmd, resume):
        gid = cmd["goal_id"]
        try:
            client = self.client(cmd["action"], cmd["type"])
            goal = to_ros(action_type(cmd["type"]).Goal(), cmd.get("fields", {}))
        except Exception as e:  # a definition that does not import, a field that does not fit
            say({"ev": "error", "goal_id": gid, "reason": str(e)})
            return
        goal_uuid = UUID(uuid=list(uuidlib.UUID(hex=cmd["uuid"]).bytes))
        if resume:
            self.follow(gid, client, ClientGoalHandle(client, goal_uuid, None))
            return

        def feedback(msg):
            say({"ev": "feedback", "goal_id": gid, "fields": to_json(msg.feedback)})

        try:
            future = client.send_goal_async(goal, feedback_callback=feedback, goal_uuid=goal_uuid)
        except Exception as e:  # a value rclpy cannot serialise
            say({"ev": "error", "goal_id": gid, "reason": str(e)})
            return

        def answered(f):
            try:
                handle = f.result()
            except Exception as e:
                say({"ev": "error", "goal_id": gid, "reason": str(e)})
                return
            if not handle.accepted:
                # Refused, or already held (a goal sent again): its result, if it has one.
                self.follow(gid, client, ClientGoalHandle(client, goal_uuid, None), refused=True)
                return
            say({"ev": "accepted", "goal_id": gid})
            self.follow(gid, client, handle)

        future.add_done_callback(answered)

    def follow(self, gid, client, handle, refused=False):
        with self.lock:
            self.handles[gid] = handle

        def done(f):
            try:
                r = f.result()
            except Exception as e:
                say({"ev": "error", "goal_id": gid, "reason": str(e)})
                return
            status = STATUS.get(r.status, "UNKNOWN")
            if refused and status == "UNKNOWN":
                say({"ev": "rejected", "goal_id": gid, "reason": "the server refused the goal"})
                return
            say({"ev": "result", "goal_id": gid, "status": status, "fields": to_json(r.result)})

        client._get_result_async(handle).add_done_callback(done)

    def cancel(self, gid):
        with self.lock:
            handle = self.handles.get(gid)
        if handle is not None:
            handle.cancel_goal_async()

    def watch(self, action, type_name):
        client = self.client(action, type_name)
        state = {"up": None}

        def check():
            up = client.server_is_ready()
            if up != state["up"]:
                state["up"] = up
                say({"ev": "server", "action": action, "up": up})

        self.node.create_timer(0.2, check)


class Server:
    """Action servers whose goals a Rust system executes: each goal waits in its own executor
    thread for the system's end of it."""

    def __init__(self, node):
        self.node = node
        self.servers = []
        self.goals = {}
        self.lock = threading.Lock()
        self.group = ReentrantCallbackGroup()

    def serve(self, cmd):
        resource = cmd["resource"]
        try:
            self.open(resource, cmd["action"], action_type(cmd["type"]))
        except Exception as e:  # a type that does not import, a name that is not a name
            say({"ev": "unserved", "resource": resource, "reason": str(e)})
            return
        say({"ev": "serving", "resource": resource})

    def open(self, resource, action, cls):

        def execute(handle):
            uid = bytes(handle.goal_id.uuid).hex()
            goal = {"handle": handle, "cls": cls, "ended": threading.Event(), "end": None}
            with self.lock:
                self.goals[uid] = goal
            say({"ev": "goal", "uuid": uid, "resource": resource, "fields": to_json(handle.request)})
            goal["ended"].wait()
            with self.lock:
                self.goals.pop(uid, None)
            end = goal["end"]
            result = cls.Result()
            try:
                to_ros(result, end.get("fields", {}))
            except Exception as e:  # the system's result does not fit the definition
                say({"ev": "error", "uuid": uid, "reason": f"result: {e}"})
            if end["op"] == "succeed":
                handle.succeed()
            elif end["op"] == "canceled" and handle.is_cancel_requested:
                handle.canceled()
            else:
                handle.abort()
            return result

        def cancel(handle):
            say({"ev": "cancel", "uuid": bytes(handle.goal_id.uuid).hex()})
            return CancelResponse.ACCEPT

        self.servers.append(
            ActionServer(
                self.node,
                cls,
                action,
                execute_callback=execute,
                cancel_callback=cancel,
                callback_group=self.group,
            )
        )

    def feedback(self, cmd):
        with self.lock:
            goal = self.goals.get(cmd["uuid"])
        if goal is None:
            return
        try:
            msg = to_ros(goal["cls"].Feedback(), cmd.get("fields", {}))
        except Exception as e:
            say({"ev": "error", "uuid": cmd["uuid"], "reason": f"feedback: {e}"})
            return
        goal["handle"].publish_feedback(msg)

    def end(self, cmd):
        with self.lock:
            goal = self.goals.get(cmd["uuid"])
        if goal is not None:
            goal["end"] = cmd
            goal["ended"].set()


def main():
    role = sys.argv[1] if len(sys.argv) > 1 else "client"
    rclpy.init()
    node = rclpy.create_node(
        sys.argv[2] if len(sys.argv) > 2 else "trace_executive",
        namespace=sys.argv[3] if len(sys.argv) > 3 and sys.argv[3] else None,
    )
    # Each goal a server runs holds a thread while its system executes it.
    executor = MultiThreadedExecutor(num_threads=64 if role == "server" else None)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    bridge = Bridge(node) if role == "client" else None
    server = Server(node) if role == "server" else None
    say({"ev": "ready"})
    for line in sys.stdin:
        try:
            cmd = json.loads(line)
            op = cmd["op"]
            if bridge and op in ("goal", "resume"):
                bridge.goal(cmd, op == "resume")
            elif bridge and op == "cancel":
                bridge.cancel(cmd["goal_id"])
            elif bridge and op == "watch":
                bridge.watch(cmd["action"], cmd["type"])
            elif server and op == "serve":
                server.serve(cmd)
            elif server and op == "feedback":
                server.feedback(cmd)
            elif server and op in ("succeed", "abort", "canceled"):
                server.end(cmd)
            else:
                raise ValueError(f"no command `{op}` for a {role}")
        except Exception as e:
            say({"ev": "error", "goal_id": None, "uuid": None, "reason": f"unreadable command: {e}"})
    if server:  # the system is gone: its goals end
        with server.lock:
            goals = list(server.goals.values())
        for goal in goals:
            goal["end"] = {"op": "abort"}
            goal["ended"].set()
    executor.shutdown()
    rclpy.shutdown()


main()
