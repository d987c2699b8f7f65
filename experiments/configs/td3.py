"""TD3 and DDPG presets (DDPG is TD3Config with one critic, no target smoothing, no policy delay)."""

import dataclasses

from experiments.configs.ppo import (
    CAMERA_RANDOMIZE,
    IDENTIFIED_ARM,
    ROBOT_RANDOMIZE,
    SORTER_ENV_PARAMS,
    SORTER_EVAL_ENV_PARAMS,
    UR5E,
)
from experiments.configs.registry import preset
from jaxarm.agents.td3 import TD3Config
from jaxarm.envs.arm2d import GOAL_UNIFORM_REACHABLE
from jaxarm.envs.peg_insert.params import RUNNING_TARGET_MAX_LEAD


@preset("TD3 on the 2-link arm, goals uniform over the reachable annulus")
def td3_arm2d() -> TD3Config:
    # gamma 0.9, not 0.99: success terminates the episode and ends the +1-per-step goal bonus, so with a long
    # horizon never completing the hold is worth more than succeeding; with gamma 0.99 the success rate fell
    # while Q grew (88% at 40k env steps, 43% at 200k). Step sizes 3e-4 steady the deterministic policy,
    # which swung between 87% and 99% with 1e-3; held constant, it still swung at the end on fresh seed 64 (98.1%
    # at 160k, 94.1% at 200k), so both are annealed to 0 over the run, as td3_peg's: tuning seeds 100-104 placed
    # 98.3-100% (2-core CPU, 2026-12-02; fresh seeds: BENCHMARKS.md#arm2d-td3-ddpg).
    return TD3Config(
        env="arm2d",
        env_params=(("goal_mode", GOAL_UNIFORM_REACHABLE),),
        actor_learning_rate=3e-4,
        critic_learning_rate=3e-4,
        anneal_learning_rate=True,
        gamma=0.9,
        total_env_steps=200_000,
        num_envs=16,
        grad_steps_per_update=4,
        eval_every_updates=2_500,  # five evaluations of 1,000 arm2d episodes, 0.15 s each on the 2-core CPU
    )


@preset("DDPG on the 2-link arm, fixed goal, as the classic tutorial ran it (its seeds spread: see the preset)")
def ddpg_arm2d_tutorial() -> TD3Config:
    # The tutorial ran 500 episodes of at most 200 steps, one gradient step per env step (it needed 54k env steps to
    # solve it). Its reward, +1 per step on the goal and nothing for completing the 50-step hold, pays a policy that
    # lingers about the goal more than one that finishes, and its deterministic policy swings between evaluations,
    # so float-level differences decide where a run ends: 24 seeds trained vmapped on the 2-core CPU (2026-11-28)
    # placed 0.0-100% (mean 89.2%, 5 of 24 under 95%); one seed placed 69.6% on one 2-core CPU and 100% on another.
    # ddpg_arm2d is the recipe that holds on every seed.
    return TD3Config(
        env="arm2d",
        hidden_sizes=(100,),
        actor_learning_rate=1e-3,
        critic_learning_rate=1e-3,
        gamma=0.9,
        tau=0.01,
        batch_size=32,
        buffer_size=30_000,
        num_critics=1,
        policy_delay=1,
        target_smoothing=False,
        num_envs=1,
        rollout_length=1,
        grad_steps_per_update=1,
        learning_starts=1_000,
        total_env_steps=30_000,
        updates_per_chunk=5_000,
        checkpoint_every_updates=25_000,
        eval_every_updates=5_000,  # at every chunk's end: 1,000 arm2d episodes take 0.15 s on the 2-core CPU
    )


@preset("DDPG on the 2-link arm, fixed goal: the tutorial's DDPG made to place on every seed (2-core CPU, ~1 min)")
def ddpg_arm2d() -> TD3Config:
    # ddpg_arm2d_tutorial's learner (one critic, no smoothing or delay, its 100-unit network, batches of 32, a
    # gradient step per env step) with four changes, each needed on the 2-core CPU (2026-11-28, 24 seeds trained
    # vmapped unless said): a success bonus of 50, so that finishing the hold pays five times more than lingering
    # (alone: worst seed 0%, mean 83%); observations standardised (worst 80%, mean 98.7%); both step sizes annealed
    # to 0 over the run, so that the policy settles where training ends (with both: seeds placed 25-100% at 45k env
    # steps); exploration noise 0.3 and 60k env steps (worst 100%, and 10 of 10 separate runs of seeds 10-19).
    # The seeds that failed before chattered between opposite saturated actions beside the goal. Seeds 0-4, never
    # tuned on, as separate runs: BENCHMARKS.md#arm2d-td3-ddpg.
    tutorial = ddpg_arm2d_tutorial()
    return dataclasses.replace(
        tutorial,
        env_params=(("success_bonus", 50.0),),
        normalize_observations=True,
        anneal_learning_rate=True,
        exploration_noise=0.3,
        total_env_steps=60_000,
    )


@preset("TD3 inserting a peg into a hole shifted at random (CPU or one GPU)")
def td3_peg() -> TD3Config:
    # Franka's link inertials and joint friction; 416k env steps with both step sizes annealed to 0: fresh seeds
    # 20-24 inserted 100% (2-core CPU, 2026-11-29). 224k at constant step sizes (100% in 68.9 s on one H100,
    # 2026-11-25) inserted 78.5% on seed 8, whose first insertions came at 160k, and each change alone fell short on
    # another seed: annealed over 224k, seed 10 13%; 416k at constant step sizes, seed 16 57% (its training
    # episodes, with exploration noise, 100%). BENCHMARKS.md#peg.
    return TD3Config(
        env="peg_insert",
        env_kwargs=(("dynamics", "identified"),),
        num_envs=64,
        rollout_length=1,
        grad_steps_per_update=8,
        batch_size=256,
        buffer_size=1_000_000,
        learning_starts=10_000,
        gamma=0.99,
        exploration_noise=0.2,
        anneal_learning_rate=True,
        total_env_steps=400_000,
        updates_per_chunk=500,
        checkpoint_every_updates=1_000,
    )


def td3_peg_constant_step_sizes() -> TD3Config:
    """td3_peg as the presets built on it were measured: 224k env steps at constant step sizes (td3_peg's annealed
    416k are untried on them)."""
    return dataclasses.replace(td3_peg(), anneal_learning_rate=False, total_env_steps=200_000)


@preset("TD3 inserting the peg with the running target and its wider lead, Franka's arm (CPU or one GPU)")
def td3_peg_running() -> TD3Config:
    # td3_peg with the sorter's running target and a 3 cm lead (RUNNING_TARGET_MAX_LEAD says why): td3_peg's 1 cm lead
    # slows its tool to a third when the joints are damped x3. The lead is what carries the damping; the running
    # target is the control the deployment loop shares. td3_peg keeps its control. Results: BENCHMARKS.md#peg.
    peg = td3_peg_constant_step_sizes()
    return dataclasses.replace(
        peg,
        env_kwargs=(*peg.env_kwargs, ("running_target", True)),
        env_params=(("max_lead", RUNNING_TARGET_MAX_LEAD),),
    )


PEG_ARM_RANDOMIZE = (
    # The robot's ranges of the randomised sorter, and the peg's own sensing and contact: home-posture noise up to the
    # held-out check's 0.2 rad, 5 mm of observation noise, peg-block friction.
    ("home_noise", "0.0..0.2"),
    ("friction", "0.3..1.0"),
    ("obs_noise", "0.0..0.005"),
    *ROBOT_RANDOMIZE,
)
PEG_RANDOMIZE = (*PEG_ARM_RANDOMIZE, ("hole_pose_noise", "0.0..0.001"), ("hole_pose_bias", "0.0..0.001"))
"""PEG_ARM_RANDOMIZE and 1 mm of noise and bias on the hole's observed pose, for the policies that observe it."""


@preset("TD3 inserting the peg under randomised robot and sensing, with the running target (CPU or one GPU)")
def td3_peg_dr() -> TD3Config:
    # td3_peg_running drawing PEG_RANDOMIZE per env at every reset, over twice its budget: at this budget no better
    # than td3_peg_running on any held-out check (BENCHMARKS.md#peg).
    return dataclasses.replace(td3_peg_running(), randomize=PEG_RANDOMIZE, total_env_steps=400_000)


@preset("TD3 inserting the peg from two 64x64 cameras (gray and depth) and the arm's state (one GPU)")
def td3_peg_pixels() -> TD3Config:
    # td3_peg with the hole seen only in the images: one Nature-DQN encoder trained by the critics' loss and read
    # by the actor (DrQ's layout), DrQ's random shift (4 pixels, as DrQ's at 84x84), 256 envs and batches of
    # 512. With an encoder per network, 64 envs and batches of 256, none of 704k env steps' training episodes
    # inserted (6 minutes). The replay keeps uint8 frames, 16 KiB per observation (2 cameras x gray and depth),
    # twice per transition: 200k transitions are 6.6 GB of GPU memory. 2M env steps with both step sizes annealed
    # to 0, as td3_peg's recipe: fresh seeds 10-14 inserted 100% each (H200, 2026-11-30 and 12-01). At
    # constant step sizes over 1M, seed 9 inserted 87.4% while its training episodes (with exploration noise)
    # succeeded 99.1%. BENCHMARKS.md#peg-pixels.
    return dataclasses.replace(
        td3_peg_pixels_constant_step_sizes(), anneal_learning_rate=True, total_env_steps=2_000_000
    )


def td3_peg_pixels_constant_step_sizes() -> TD3Config:
    """td3_peg_pixels as the presets built on it were measured: 1.02M env steps at constant step sizes."""
    return dataclasses.replace(
        td3_peg_constant_step_sizes(),
        env="peg_insert_pixels",
        encoder="nature",
        encoder_features=256,
        shared_encoder=True,
        random_shift_pad=4,
        num_envs=256,
        batch_size=512,
        learning_starts=20_000,
        buffer_size=200_000,
        total_env_steps=1_000_000,
        updates_per_chunk=1_000,
        checkpoint_every_updates=5_000,
    )


@preset("TD3 inserting the peg from cameras under randomised robot, sensing and cameras, running target (one GPU)")
def td3_peg_pixels_dr() -> TD3Config:
    # td3_peg_pixels with td3_peg_dr's control and ranges and the cameras' own (the hole is in the images alone, so
    # no hole-pose ranges). td3_peg_pixels trains at nominal physics: its seed 6 inserted 62.5% in stock MuJoCo with
    # menagerie's Panda (64.5% with the loop's limits off), where the randomised state policies held 96.5-100%
    # (BENCHMARKS.md#transfer). Twice td3_peg_pixels' budget, as td3_peg_dr takes over td3_peg_running.
    pixels, randomised = td3_peg_pixels_constant_step_sizes(), td3_peg_dr()
    return dataclasses.replace(
        pixels,
        env_kwargs=randomised.env_kwargs,
        env_params=randomised.env_params,
        randomize=(*PEG_ARM_RANDOMIZE, *CAMERA_RANDOMIZE),
        total_env_steps=2_000_000,
    )


@preset("TD3 inserting the peg with a UR5e, Universal Robots' link inertials (CPU or one GPU)")
def td3_peg_ur5e() -> TD3Config:
    # td3_peg on the arm of the tutorial the task comes from: the same task code, observation and actions (5 mm per
    # step in x, y, z), the UR5e's model, limits and dynamics (`dynamics=identified` writes a robot's identified links).
    peg = td3_peg_constant_step_sizes()
    return dataclasses.replace(peg, env_kwargs=(*peg.env_kwargs, *UR5E))


@preset("TD3 inserting the peg with a UR5e from two 64x64 cameras (gray and depth) and the arm's state (one GPU)")
def td3_peg_ur5e_pixels() -> TD3Config:
    # td3_peg_pixels' learner on the UR5e: the scene camera and the camera on the UR5e's gripper. As the tutorial
    # drew the hole's and the floor's colours every episode, the block and the table take a gray each episode,
    # up to 0.4 off their own (the block's 0.50, the table's 0.50).
    pixels = td3_peg_pixels_constant_step_sizes()
    return dataclasses.replace(
        pixels, env_kwargs=(*pixels.env_kwargs, *UR5E), env_params=(("surface_gray_spread", 0.4),)
    )


@preset("TD3 on the Panda sorter, 1 object, Franka's arm, C51 critics and a spread of exploration noise (one GPU)")
def td3_sorter() -> TD3Config:
    # The env settings and training-only curricula of ppo_sorter (experiments/configs/ppo.py says why);
    # rewards scaled as there; observations standardised as PPO's are. At GPU scale: 4,096 envs (Warp on an
    # NVIDIA GPU) x 4 steps per update, 8 gradient steps of 8,192 (each transition replayed 4 times), 3-step
    # returns. C51 critics on [-2, 8] (the scaled returns lie in about [-0.5, 6]), exploration std spread over
    # the envs from 0.4/4096 to 0.4, and fast targets (tau 0.1): without the three, 0.3% after 75-88M env steps
    # (BENCHMARKS.md#td3-sorter has the ablation).
    return TD3Config(
        env="panda_sort",
        env_kwargs=(("impl", "auto"), ("max_envs", 4096), *IDENTIFIED_ARM),
        normalize_observations=True,
        env_params=SORTER_ENV_PARAMS,
        eval_env_params=SORTER_EVAL_ENV_PARAMS,
        num_envs=4096,
        rollout_length=4,
        grad_steps_per_update=8,
        batch_size=8192,
        buffer_size=4_000_000,
        learning_starts=200_000,
        n_step=3,
        gamma=0.97,
        reward_scale=0.01,
        critic_atoms=101,
        value_min=-2.0,
        value_max=8.0,
        tau=0.1,
        exploration_noise=0.4,
        mixed_exploration_noise=True,
        # ~3.1e5 env steps/s on an H200 (Warp, C51 critics): ~11 minutes, inside the 15 of BENCHMARKS.md#td3-sorter.
        # At 100M env steps (7.5 min) one seed of five placed 67%; at 180M the worst placed 97.9%.
        total_env_steps=200_000_000,
        updates_per_chunk=100,
        checkpoint_every_updates=500,
        eval_episodes=1000,
    )
