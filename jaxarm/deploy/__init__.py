"""What runs next to a robot: each control tick, the observation a policy was trained on, formed from what the
robot reads, the exported numpy policy (`jaxarm.export.numpy_policy`), and the env's own controller (IK, running
target, joint limits) in numpy, within the arm's joint speed and acceleration limits.

`loop.py` keeps the tick and the `Robot` it drives; `sort.py` and `peg.py` are the sorter's and the peg's
observation and control; `kinematics.py` poses the arm with MuJoCo's C library; `ik.py` is the env's IK maths in
numpy; `limits.py` the datasheet's limits; `scoring.py` the tasks' scoring; `mujoco_robot.py` is stock MuJoCo playing
the robot; `camera.py` draws a scene's cameras as the envs observe them and gives a camera policy its observation.
`stream.py` turns the 25 Hz targets into a jerk-limited 1 kHz servo stream (Ruckig); `driver.py` and
`remote.py` are a robot process behind a socket and the policy's side of it, `wire.py` their messages and deadlines,
`clock.py` the policy's wall-clock ticks, `rehearsal.py` a real-time episode through them (the robot extra: ruckig,
pyzmq); `adapters.py` drives a Panda through franky-control or a UR5e through ur_rtde (the adapters extra; not run on
hardware here). These import numpy and mujoco (and the extras' packages) alone, so a robot's computer needs no
JAX: `files.py` loads a controller from the deploy.json and robot.mjb that `python -m experiments.export` writes.
`jaxarm.deployable` (JAX), above this package and the envs, reads a task's numbers from a jaxarm env and its params.
No module here imports JAX or `jaxarm.envs` (tests/deploy/test_imports.py).
"""
