"""TD3 and DDPG presets (DDPG is TD3Config with one critic, no target smoothing, no policy delay)."""

import dataclasses

from experiments.configs.ppo import FRANKA_ARM, ROBOT_RANDOMIZE, SORTER_ENV_PARAMS, SORTER_EVAL_ENV_PARAMS
from experiments.configs.registry import preset
from jaxarm.agents.td3 import TD3Config
from jaxarm.envs.arm2d import GOAL_UNIFORM_REACHABLE
from jaxarm.envs.peg_insert.params import RUNNING_TARGET_MAX_LEAD


@preset("TD3 on the 2-link arm, goals uniform over the reachable annulus")
def td3_arm2d() -> TD3Config:
    # gamma 0.9, not 0.99: success terminates the episode and ends the +1-per-step goal bonus, so with a long
    # horizon never completing the hold is worth more than succeeding; with gamma 0.99 the success rate fell
    # while Q grew (88% at 40k env steps, 43% at 200k). Step sizes 3e-4 steady the deterministic policy,
    # which swung between 87% and 99% with 1e-3. Measured: 97.6% of 1,000 fresh episodes at 200k env steps.
    return TD3Config(
        env="arm2d",
        env_params=(("goal_mode", GOAL_UNIFORM_REACHABLE),),
        actor_learning_rate=3e-4,
        critic_learning_rate=3e-4,
        gamma=0.9,
        total_env_steps=200_000,
        num_envs=16,
        grad_steps_per_update=4,
    )


@preset("DDPG on the 2-link arm, fixed goal, close to the classic tutorial, with a success bonus")
def ddpg_arm2d() -> TD3Config:
    # The tutorial ran 500 episodes of at most 200 steps, one gradient step per env step (it needed 54k env
    # steps to solve it). Its reward, +1 per step on the goal and nothing for completing the 50-step hold, pays
    # a policy that lingers about the goal more than one that finishes (with gamma 0.9, stepping off for a step
    # and holding again is worth ~9 at the hold's last step, finishing 1), so a run's success swings between evaluations
    # (from 100% to 59-95% and back) and float-level differences decide where it ends: one seed placed 69.6% on
    # one 2-core CPU and 100% on another, and 58.8% trained vmapped beside four others. A success bonus of 50
    # makes finishing pay five times more: five seeds, vmapped, placed 98.6-100% (BENCHMARKS.md).
    return TD3Config(
        env="arm2d",
        env_params=(("success_bonus", 50.0),),
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
    )


@preset("DDPG on the 2-link arm, fixed goal, tuned: 4 envs, replay ratio 1, gamma 0.9, slow actor and targets")
def ddpg_arm2d_tuned() -> TD3Config:
    # ddpg_arm2d's success bonus (it says why), 4 envs, batches of 128 and a slower actor. With the tutorial's
    # reward, actor step 3e-4 and tau 0.005, five seeds placed 86-100% at 20k env steps on the 2-core CPU; with
    # the bonus alone one of five vmapped seeds placed 43.9%, at 40k env steps one 83.9%. Actor step 1e-4 and
    # tau 0.002 steady it: five seeds, vmapped, placed 100% (BENCHMARKS.md).
    return TD3Config(
        env="arm2d",
        env_params=(("success_bonus", 50.0),),
        hidden_sizes=(64, 64),
        actor_learning_rate=1e-4,
        critic_learning_rate=1e-3,
        gamma=0.9,
        tau=0.002,
        batch_size=128,
        buffer_size=100_000,
        num_critics=1,
        policy_delay=1,
        target_smoothing=False,
        num_envs=4,
        rollout_length=1,
        grad_steps_per_update=4,
        learning_starts=1_000,
        total_env_steps=20_000,
        updates_per_chunk=1_250,
        checkpoint_every_updates=2_500,
    )


@preset("TD3 inserting a peg into a hole shifted at random (one GPU; on a CPU, shrink total_env_steps)")
def td3_peg() -> TD3Config:
    # With Franka's link inertials and joint friction: 100.0% of 1,000 fresh episodes inserted after 224k env
    # steps in 68.9 s (one H100, MJX-JAX, 2026-11-25; the nominal arm: 71.1 s).
    return TD3Config(
        env="peg_insert",
        env_kwargs=(("dynamics", "franka"),),
        num_envs=64,
        rollout_length=1,
        grad_steps_per_update=8,
        batch_size=256,
        buffer_size=1_000_000,
        learning_starts=10_000,
        gamma=0.99,
        exploration_noise=0.2,
        total_env_steps=200_000,
        updates_per_chunk=500,
        checkpoint_every_updates=1_000,
    )


@preset("TD3 inserting the peg with the running target and its wider lead, Franka's arm (CPU or one GPU)")
def td3_peg_running() -> TD3Config:
    # td3_peg with the sorter's running target and a 3 cm lead (RUNNING_TARGET_MAX_LEAD says why): td3_peg's 1 cm lead
    # slows its tool to a third when the joints are damped x3. The lead is what carries the damping; the running
    # target is the control the deployment loop shares. td3_peg keeps its control. Results: BENCHMARKS.md#peg.
    peg = td3_peg()
    return dataclasses.replace(
        peg,
        env_kwargs=(*peg.env_kwargs, ("running_target", True)),
        env_params=(("max_lead", RUNNING_TARGET_MAX_LEAD),),
    )


PEG_RANDOMIZE = (
    # The robot's ranges of the randomised sorter, and the peg's own sensing and contact: home-posture noise up to the
    # held-out check's 0.2 rad, 5 mm of observation noise, 1 mm of hole-pose noise and bias, peg-block friction.
    ("home_noise", "0.0..0.2"),
    ("friction", "0.3..1.0"),
    ("obs_noise", "0.0..0.005"),
    *ROBOT_RANDOMIZE,
    ("hole_pose_noise", "0.0..0.001"),
    ("hole_pose_bias", "0.0..0.001"),
)


@preset("TD3 inserting the peg under randomised robot and sensing, with the running target (CPU or one GPU)")
def td3_peg_dr() -> TD3Config:
    # td3_peg_running drawing PEG_RANDOMIZE per env at every reset, over twice its budget: at this budget no better
    # than td3_peg_running on any held-out check (BENCHMARKS.md#peg).
    return dataclasses.replace(td3_peg_running(), randomize=PEG_RANDOMIZE, total_env_steps=400_000)


@preset("TD3 inserting the peg from two 64x64 cameras (gray and depth) and the arm's state (one GPU)")
def td3_peg_pixels() -> TD3Config:
    # td3_peg with the hole seen only in the images: one Nature-DQN encoder trained by the critics' loss and read
    # by the actor (DrQ's layout), DrQ's random shift (4 pixels, as DrQ's at 84x84), 256 envs and batches of
    # 512. So, on one H100 (2026-11-25), seeds 0-2 inserted 100.0%, 95.3% and 100.0% of 1,000 fresh episodes
    # after 1.02M env steps in 128-132 s. With an encoder per network, 64 envs and batches of 256, none of
    # 704k env steps' training episodes inserted (6 minutes). The replay keeps uint8 frames, 16 KiB per
    # observation (2 cameras x gray and depth), twice per transition: 200k transitions are 6.6 GB of GPU memory.
    return dataclasses.replace(
        td3_peg(),
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
        env_kwargs=(("impl", "auto"), ("max_envs", 4096), *FRANKA_ARM),
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
        # ~2.9e5 env steps/s on Warp with C51 critics: about 17 minutes; it is solved long before.
        total_env_steps=300_000_000,
        updates_per_chunk=100,
        checkpoint_every_updates=500,
        eval_episodes=1000,
    )
