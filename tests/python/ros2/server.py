"""A real rclpy action server of `test_msgs/action/Fibonacci` at `/fibonacci`, for
tests/it/ros2.rs. By the goal's `order`:
  1..=20   the sequence, one feedback per number, STEP seconds apart (argv[1], default 0.05)
  13       ABORTED after its first feedback
  >= 100   runs until canceled (a feedback every STEP seconds)
  < 0      refused
It prints `ready` once serving, `goal ORDER` for each goal accepted and `cancel` for each
cancel asked."""

import sys
import threading
import time

import rclpy
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.executors import MultiThreadedExecutor
from rclpy.callback_groups import ReentrantCallbackGroup
from test_msgs.action import Fibonacci

STEP = float(sys.argv[1]) if len(sys.argv) > 1 else 0.05


def say(line):
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def goal_callback(goal):
    return GoalResponse.REJECT if goal.order < 0 else GoalResponse.ACCEPT


def cancel_callback(_handle):
    say("cancel")
    return CancelResponse.ACCEPT


def execute(handle):
    order = handle.request.order
    say(f"goal {order}")
    seq = [0, 1]
    feedback = Fibonacci.Feedback()
    n = 0
    while True:
        if handle.is_cancel_requested:
            handle.canceled()
            return Fibonacci.Result(sequence=seq)
        if order < 100 and n >= order - 1:
            break
        seq.append(seq[-1] + seq[-2])
        feedback.sequence = seq
        handle.publish_feedback(feedback)
        n += 1
        if order == 13:
            handle.abort()
            return Fibonacci.Result(sequence=seq)
        time.sleep(STEP)
    handle.succeed()
    return Fibonacci.Result(sequence=seq[: order + 1])


def main():
    rclpy.init()
    node = rclpy.create_node("fibonacci_server")
    ActionServer(
        node,
        Fibonacci,
        "fibonacci",
        execute_callback=execute,
        goal_callback=goal_callback,
        cancel_callback=cancel_callback,
        callback_group=ReentrantCallbackGroup(),
    )
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    say("ready")
    executor.spin()


main()
