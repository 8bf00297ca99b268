"""The runtime monitor in the environments: the shipped policy acting through a monitored
environment is `host-sim eval --controller monitored`, episode for episode; a tight
envelope's fallback takes over from an agent that only pushes left; an envelope file is read
as eval reads it."""

import json

import numpy as np
import pytest

import cartpole_ddqn

from conftest import REPO, run

# A frozen encoder now and then: the monitor's fallback decides about a tenth of the periods.
SCENARIO, EPISODES, HORIZON, SEED = "encoder+stuck", 12, 1000, 3


def episodes(env, agent, count, seed):
    """Per episode: periods, whether it terminated, periods the fallback decided."""
    out = []
    obs, _ = env.reset(seed=seed)
    for e in range(count):
        if e:
            obs, _ = env.reset()
        n = took = 0
        while True:
            obs, _, terminated, truncated, info = env.step(agent(obs))
            n += 1
            took += info.get("fallback", False)
            if terminated or truncated:
                break
        out.append((n, terminated, took))
    return out


def test_the_shipped_policy_through_the_monitored_env_is_evals_monitored_row(tools):
    args = ["--scenario", SCENARIO, "--episodes", EPISODES, "--horizon", HORIZON, "--seed", SEED]
    want = json.loads(run(tools["host-sim"], "eval", "--controller", "monitored", "--json", *args))
    want = want["rows"][0]
    env = cartpole_ddqn.TwinEnv(scenario=SCENARIO, max_episode_steps=HORIZON, envelope="shipped")
    got = episodes(env, cartpole_ddqn.shipped().act, EPISODES, SEED)
    steps = sum(n for n, _, _ in got)
    assert sum(t for _, t, _ in got) == want["failures"]
    assert steps / EPISODES == pytest.approx(want["mean_steps"], rel=1e-12)
    assert sum(f for _, _, f in got) / steps == pytest.approx(want["fallback_share"], rel=1e-12)
    assert want["fallback_share"] > 0.01


def test_a_tight_envelope_takes_over_from_an_agent_that_only_pushes_left(tmp_path):
    def left(_):
        return 0

    alone = episodes(cartpole_ddqn.TwinEnv(max_episode_steps=500), left, 5, 1)
    assert all(t for _, t, _ in alone) and max(n for n, _, _ in alone) < 60, alone
    # The shipped envelope is as wide as the shipped policy's own excursions under pushes
    # (its angle bound lies past the termination angle): it leaves such an agent to fall.
    shipped = episodes(cartpole_ddqn.TwinEnv(max_episode_steps=500, envelope="shipped"), left, 5, 1)
    assert [n for n, _, _ in shipped] == [n for n, _, _ in alone]
    path = tmp_path / "tight.json"
    path.write_text(json.dumps({"envelope": [1.0, 1.5, 0.05, 0.8]}))
    monitored = episodes(cartpole_ddqn.TwinEnv(max_episode_steps=500, envelope=path), left, 5, 1)
    assert all(n == 500 and not t for n, t, _ in monitored), monitored
    assert all(0 < f < n for n, _, f in monitored), monitored


def test_an_envelope_file_is_read_as_eval_reads_it(tmp_path):
    # An envelope of nothing: every reading is outside, so the fallback decides every period.
    path = tmp_path / "none.json"
    path.write_text(json.dumps({"envelope": [0.0, 0.0, 0.0, 0.0]}))
    env = cartpole_ddqn.TwinEnv(max_episode_steps=200, envelope=path)
    got = episodes(env, lambda _: 1, 3, 0)
    assert all(n == 200 and not t and f == n for n, t, f in got), got


def test_the_vector_env_reports_each_worlds_fallback():
    env = cartpole_ddqn.TwinVectorEnv(4, max_episode_steps=100, envelope="shipped")
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(4, dtype=np.int64))
    single = cartpole_ddqn.TwinEnv(max_episode_steps=100, envelope="shipped")
    for i in range(4):
        single.reset(seed=i)
        assert info["fallback"][i] == single.step(0)[4]["fallback"]
    assert info["_fallback"].all()


@pytest.mark.parametrize(
    "envelope, words",
    [
        ("/nonexistent/envelope.json", "^envelope /nonexistent/envelope.json"),
        ("/", "^envelope /: expected a regular file"),
        (3, "envelope must be None"),
    ],
)
def test_a_bad_envelope_raises_value_error_naming_it(tmp_path, envelope, words):
    with pytest.raises(ValueError, match=words):
        cartpole_ddqn.TwinEnv(envelope=envelope)
    bad = tmp_path / "bad.json"
    bad.write_text('{"envelope": [1, 2, -3, 4]}')
    with pytest.raises(ValueError, match="bad.json"):
        cartpole_ddqn.TwinEnv(envelope=bad)


@pytest.mark.filterwarnings("ignore:the policy was trained for another rig")
def test_an_envelope_measured_on_another_machine_is_refused():
    """The shipped envelope, and the committed file of it, were measured on Gymnasium's
    machine: on the desk rig they bound the readings of another plant."""
    desk = REPO / "rigs" / "desk.toml"
    measured = REPO / "docs" / "results" / "envelope.json"
    says = "envelope was measured on another machine"
    with pytest.raises(ValueError, match=says):
        cartpole_ddqn.evaluate(controller="monitored", rig=desk, episodes=1, horizon=2)
    with pytest.raises(ValueError, match=says):
        cartpole_ddqn.TwinEnv(rig=desk, envelope=measured)
    cartpole_ddqn.TwinEnv(envelope=measured)
