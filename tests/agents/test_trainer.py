"""Training success over a window of env steps, on hand-made states whose answer is known."""

import jax.numpy as jnp
import numpy as np

from jaxarm.agents.common.trainer import summarise_episodes
from jaxarm.envs import EnvState
from jaxarm.envs.base import EpisodeStats


def stats(length, success, return_=None) -> EpisodeStats:
    length = jnp.asarray(length, jnp.int32)
    return EpisodeStats(
        return_=jnp.asarray(length if return_ is None else return_, jnp.float32),
        length=length,
        success=jnp.asarray(success, jnp.bool_),
        nan_actions=jnp.zeros_like(length),
        diverged=jnp.zeros(length.shape, jnp.bool_),
    )


def window(terminated, truncated, episode: EpisodeStats, last_episode: EpisodeStats) -> EnvState:
    """States [T, B] after each step of a window; only what a summary reads is filled in."""
    terminated = jnp.asarray(terminated, jnp.bool_)
    zeros = jnp.zeros(terminated.shape, jnp.float32)
    return EnvState(
        sim=(),
        obs=zeros,
        reward=zeros,
        terminated=terminated,
        truncated=jnp.asarray(truncated, jnp.bool_),
        final_obs=zeros,
        step_count=episode.length,
        episode=episode,
        last_episode=last_episode,
        info=(),
        key=zeros,
    )


def test_training_success_counts_first_episodes_still_running_as_failures_so_far():
    # Three steps of five envs (columns): 0 in its first episode all along; 1 succeeds at its first episode's
    # 30th step (the window's second); 2 runs an episode after one it finished before the window; 3 has met the
    # goal in its first episode, which goes on; 4 runs out its time limit (200 steps) at the window's last step.
    no, yes = False, True
    terminated = [[no, no, no, no, no], [no, yes, no, no, no], [no, no, no, no, no]]
    truncated = [[no, no, no, no, no], [no, no, no, no, no], [no, no, no, no, yes]]
    episode = stats(
        length=[[50, 29, 10, 40, 198], [51, 0, 11, 41, 0], [52, 1, 12, 42, 0]],
        success=[[no, no, no, yes, no], [no, no, no, yes, no], [no, no, no, yes, no]],
    )
    last_episode = stats(
        length=[[0, 0, 120, 0, 0], [0, 30, 120, 0, 0], [0, 30, 120, 0, 200]],
        success=[[no, no, yes, no, no], [no, yes, yes, no, no], [no, yes, yes, no, no]],
    )
    summary = summarise_episodes(window(terminated, truncated, episode, last_episode))
    assert summary.episodes == 2, "env 1's success and env 4's time limit"
    assert summary.judged == 3, "and env 0's first episode, a failure so far; envs 2 and 3 are judged when they end"
    np.testing.assert_allclose(summary.success_rate, 1 / 3)  # finished episodes alone would say 1/2
    np.testing.assert_allclose(summary.length_mean, (30 + 200) / 2)
    np.testing.assert_allclose(summary.return_mean, (30 + 200) / 2)


def test_once_every_env_has_finished_an_episode_training_success_is_that_of_the_finished_ones():
    no, yes = False, True
    episode = stats(length=[[0, 7, 0]], success=[[no, no, no]])
    last_episode = stats(length=[[40, 90, 200]], success=[[yes, no, no]])
    summary = summarise_episodes(window([[yes, no, no]], [[no, no, yes]], episode, last_episode))
    assert summary.episodes == summary.judged == 2
    np.testing.assert_allclose(summary.success_rate, 1 / 2)


def test_a_window_in_which_nothing_is_judged_gives_zeros_not_nan():
    no = False
    episode = stats(length=[[3, 4]], success=[[no, True]])
    last_episode = stats(length=[[60, 0]], success=[[no, no]])
    summary = summarise_episodes(window([[no, no]], [[no, no]], episode, last_episode))
    assert summary.episodes == summary.judged == 0
    assert summary.success_rate == summary.return_mean == 0
