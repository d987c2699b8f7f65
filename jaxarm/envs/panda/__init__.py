"""The Franka Panda model and its end-effector control, shared by the MJX arm envs."""
