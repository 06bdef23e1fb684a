"""Webots controller: a learned behavior-hmm behavior drives a differential-drive robot.

UNTESTED against a running Webots (it cannot be installed where this was written): the
logic it calls (``webots_logic.py``) is tested without Webots; this file only binds it
to Webots' Python API. See ../../README.md.

controllerArgs (in the robot node), all optional but the first::

    MODEL.bhmm [goal=angle=0,distance=0.05] [target=TARGET] [body_radius=0.037]
               [object_radius=0.05] [wheel_scale=1.05] [left=left wheel motor]
               [right=right wheel motor]

The robot node must be a Supervisor (``supervisor TRUE``); the object is found by its
DEF name (``target``).
"""

from __future__ import annotations

import sys

from controller import Supervisor  # Webots' own Python module
from webots_logic import WebotsBehavior, sensor_reading

from behavior_hmm.errors import ModelFileError
from behavior_hmm.models import CBLM, SBLM


def _options(argv: list[str]) -> tuple[str, dict[str, str]]:
    if not argv:
        sys.exit("behavior_hmm_controller: give the model file in controllerArgs")
    options = {}
    for item in argv[1:]:
        key, _, value = item.partition("=")
        options[key.strip()] = value.strip()
    return argv[0], options


def _goal(text: str | None) -> dict[str, float] | None:
    if not text:
        return None
    goal = {}
    for item in text.split(","):
        key, _, value = item.partition("=")
        goal[key.strip()] = float(value)
    return goal


def _load(path: str) -> object:
    try:
        return SBLM.load(path)
    except ModelFileError:
        return CBLM.load(path)


def main() -> None:
    model_path, options = _options(sys.argv[1:])
    robot = Supervisor()
    time_step = int(robot.getBasicTimeStep())
    left = robot.getDevice(options.get("left", "left wheel motor"))
    right = robot.getDevice(options.get("right", "right wheel motor"))
    for motor in (left, right):
        motor.setPosition(float("inf"))  # velocity control
        motor.setVelocity(0.0)
    me = robot.getSelf()
    target = robot.getFromDef(options.get("target", "TARGET"))
    if target is None:
        sys.exit(f"behavior_hmm_controller: no node DEF {options.get('target', 'TARGET')}")
    behavior = WebotsBehavior(
        _load(model_path),
        _goal(options.get("goal")),
        basic_time_step_ms=time_step,
        max_wheel_speed=min(left.getMaxVelocity(), right.getMaxVelocity()),
        wheel_scale=float(options.get("wheel_scale", 1.0)),
    )
    body_radius = float(options.get("body_radius", 0.037))
    object_radius = float(options.get("object_radius", 0.05))
    while robot.step(time_step) != -1:
        reading = sensor_reading(
            me.getPosition(),
            me.getOrientation(),
            me.getVelocity(),
            target.getPosition(),
            body_radius=body_radius,
            object_radius=object_radius,
        )
        command = behavior.step(reading)
        left.setVelocity(command.left)
        right.setVelocity(command.right)
        if command.done:
            print(f"behavior_hmm_controller: done ({command.reason})")
            break
    left.setVelocity(0.0)
    right.setVelocity(0.0)
    robot.step(time_step)  # let the stop take effect


if __name__ == "__main__":
    main()
