"""Evaluation: the rows `host-sim eval --json` prints for the same arguments."""

import itertools
import re
import json
import numpy as np

import pytest

import cartpole_ddqn

from conftest import REPO, run


@pytest.mark.parametrize(
    "scenario, controllers, rig",
    [
        ("noise+delay=2+push", ["policy", "lqr", "lqr-predict", "rule"], None),
        ("encoder=1024", ["policy-int", "monitored"], None),
        ("noise", ["lqr"], REPO / "rigs" / "desk.toml"),
    ],
)
def test_rows_are_the_commands(tools, scenario, controllers, rig):
    args = ["--scenario", scenario, "--controller", ",".join(controllers), "--episodes", "60"]
    args += ["--horizon", "200,400", "--seed", "9"] + (["--rig", rig] if rig else [])
    want = json.loads(run(tools["host-sim"], "eval", "--json", *args))
    got = cartpole_ddqn.evaluate(
        scenario=scenario, controller=controllers, episodes=60, horizon=[200, 400], seed=9, rig=rig
    )
    assert got == want["rows"]
    assert {"success_rate", "success_ci95", "failures", "rms_theta_deg", "rms_x_m"} <= set(got[0])


def test_refusals_raise_value_error():
    with pytest.raises(ValueError, match="controller"):
        cartpole_ddqn.evaluate(controller="pid")
    with pytest.raises(ValueError, match="episodes"):
        cartpole_ddqn.evaluate(episodes=0)
    with pytest.raises(ValueError, match="monitored"):
        cartpole_ddqn.evaluate(cartpole_ddqn.load(REPO / "shipped" / "policy.safetensors"), controller="monitored")


def test_a_policy_no_controller_reads_is_refused_as_the_command_refuses_it():
    """Given with baselines alone, it changed nothing, without a word."""
    shipped = cartpole_ddqn.load(REPO / "shipped" / "policy.safetensors")
    read_by = "is read by the controllers that run its network or round to its levels"
    with pytest.raises(ValueError, match=f"^policy {read_by} .* found lqr, rule$"):
        cartpole_ddqn.evaluate(shipped, controller=["lqr", "rule"], episodes=1, horizon=2)
    with pytest.raises(ValueError, match=f"^levels {read_by}"):
        cartpole_ddqn.evaluate(shipped, controller="lqr", episodes=1, horizon=2, levels=[-1, 1])
    with pytest.raises(ValueError, match=f"^levels {read_by}"):
        cartpole_ddqn.evaluate(controller="lqr", episodes=1, horizon=2, levels=[-1, 1])
    rows = cartpole_ddqn.evaluate(shipped, controller=["lqr", "policy"], episodes=1, horizon=2)
    assert [r["controller"] for r in rows] == ["lqr", "policy"]


def test_a_refined_controller_is_refused_for_a_policy_of_two_levels():
    """Both its levels are ends: the row would be the unrefined one's, bit for bit."""
    with pytest.raises(ValueError, match="its two levels are both ends"):
        cartpole_ddqn.evaluate(controller=["policy", "policy-refined"], episodes=1, horizon=2)


@pytest.mark.parametrize("policy", ["shipped/policy.safetensors", 0])
def test_a_policy_that_is_no_policy_raises_type_error(policy):
    """A path is for cartpole_ddqn.load; evaluate takes what it returns."""
    with pytest.raises(TypeError, match=r"^policy: expected a Policy from cartpole_ddqn.load, or None; found "):
        cartpole_ddqn.evaluate(policy=policy, episodes=1, horizon=2)


@pytest.mark.parametrize("episodes", [1.5, 2.0, "3", None])
def test_a_count_of_episodes_that_is_no_int_raises_type_error(episodes):
    """As a float seed does: 1.5 is not cut to 1."""
    with pytest.raises(TypeError, match=r"^episodes must be an int \(a whole number\); found "):
        cartpole_ddqn.evaluate(controller="lqr", episodes=episodes, horizon=2)


@pytest.mark.parametrize("episodes", [0, -1, cartpole_ddqn.MAX_EPISODES + 1, 2**64, -(2**64)])
def test_a_count_of_episodes_out_of_range_names_the_argument_and_the_range(episodes):
    """2**64 raised an OverflowError from the native conversion, naming neither."""
    most = cartpole_ddqn.MAX_EPISODES
    with pytest.raises(ValueError, match=rf"^episodes must be in \[1, {most}\]; found {episodes}$"):
        cartpole_ddqn.evaluate(controller="lqr", episodes=episodes, horizon=2)
    assert cartpole_ddqn.evaluate(controller="lqr", episodes=np.int64(1), horizon=2)[0]["episodes"] == 1


def test_provenance_is_the_tools_record(tools):
    """A script's results record the run as the tools' do: the same fields, the same
    revision and machine, its own command."""
    tool = json.loads(run(tools["host-sim"], "eval", "--json", "--episodes", "1", "--scenario", "nominal"))
    theirs = tool["provenance"]
    assert (theirs["tool"], theirs["argv"][:2]) == ("host-sim", ["eval", "--json"])
    ours = cartpole_ddqn.provenance("examples/sb3_dqn.py", ["--steps", 10])
    assert set(ours) == set(theirs)
    assert (ours["tool"], ours["argv"]) == ("examples/sb3_dqn.py", ["--steps", "10"])
    for key in ("revision", "dirty", "nproc", "cpu"):
        assert ours[key] == theirs[key], key
    assert ours["date"][:10] == theirs["date"][:10] or ours["date"] >= theirs["date"]


class Counted:
    """A list of `n` items that may be counted but not read: reading it fails the test."""

    def __init__(self, n):
        self.n = n

    def __len__(self):
        return self.n

    def __iter__(self):
        raise AssertionError("a list was built")


ROWS = "horizon x scenario x controller must make at most 10000 rows; found"


def test_too_many_rows_are_refused_before_any_list_is_built():
    with pytest.raises(ValueError, match=f"^{ROWS} 20000000$"):
        cartpole_ddqn.evaluate(scenario=Counted(20_000_000), controller="lqr", episodes=1, horizon=10)
    with pytest.raises(ValueError, match=f"^{ROWS} 30000000$"):
        cartpole_ddqn.evaluate(controller="lqr", episodes=1, horizon=range(1, 30_000_001))
    with pytest.raises(ValueError, match=f"^{ROWS} 20000$"):
        cartpole_ddqn.evaluate(scenario=Counted(200), horizon=Counted(100), episodes=1)
    # Counted only by reading it, a list is read one item past the limit and no further.
    endless = itertools.count(1)
    with pytest.raises(ValueError, match=f"^{ROWS} 10001$"):
        cartpole_ddqn.evaluate(controller="lqr", episodes=1, horizon=endless)
    assert next(endless) == cartpole_ddqn.MAX_ROWS + 2
    rows = cartpole_ddqn.evaluate(controller="lqr", episodes=1, horizon=(h for h in (10, 20)))
    assert [r["horizon"] for r in rows] == [10, 20]


def test_a_row_asked_for_twice_is_refused_as_the_command_refuses_it():
    """Each row once, as eval's rows: by the world a scenario builds, not its spelling."""
    cases = [
        (dict(controller=["lqr", "lqr"]), "controller: expected each row once, found lqr twice"),
        (dict(horizon=[10, 10]), "horizon: expected each row once, found 10 twice"),
        (dict(scenario=["noise+delay", "delay+noise"]), '"noise+delay" and "delay+noise", one scenario spelt twice'),
        (dict(scenario=["noise", "noise=1"]), '"noise" and "noise=1", one scenario spelt twice'),
        # Stuck in every period whatever K: one world, and K past EVERY a slip.
        (dict(scenario=["stuck=5/5", "stuck=1/1"]), '"stuck=5/5" and "stuck=1/1", which build one world'),
        (dict(scenario=["stuck=5/5", "stuck=9/5"]), "expected K at most EVERY in every world"),
    ]
    cases.append((dict(horizon=[10, 10.9]), "horizon must be a whole number of periods; found 10.9"))
    cases.append((dict(horizon=10.0), "horizon must be a whole number of periods; found 10.0"))
    # Past the native conversion's range: an OverflowError named neither.
    top = cartpole_ddqn.MAX_HORIZON
    for h in (2**40, -1, 0, [10, 10**30], np.uint64(2**64 - 1)):
        found = h[-1] if isinstance(h, list) else h
        cases.append((dict(horizon=h), f"horizon must be in [1, {top}]; found {found}"))
    for kwargs, why in cases:
        with pytest.raises(ValueError, match=re.escape(why)):
            cartpole_ddqn.evaluate(**{"controller": "lqr", "episodes": 1, "horizon": 10, **kwargs})


@pytest.mark.parametrize(
    "what, value",
    [("scenario", {"noise": 5, "delay": 3}), ("scenario", {"noise", "delay"}), ("controller", {"lqr", "rule"}),
     ("controller", {"lqr": 1}), ("horizon", {10, 20})],
)
def test_a_dict_or_a_set_as_a_list_raises_type_error(what, value):
    """A dict would be read by its keys, its values dropped; a set's order would be the rows'."""
    kind = type(value).__name__
    with pytest.raises(TypeError, match=f"^{what} must be a {what} or a list of them; found {kind} "):
        cartpole_ddqn.evaluate(**{"controller": "lqr", "episodes": 1, "horizon": 2, what: value})
    rows = cartpole_ddqn.evaluate(scenario=("noise", "delay"), controller=["lqr", "rule"], episodes=1, horizon=2)
    assert [(r["scenario"], r["controller"]) for r in rows] == [
        ("noise", "lqr"), ("noise", "rule"), ("delay", "lqr"), ("delay", "rule")
    ]


def test_a_seed_past_64_bits_or_a_name_as_bytes_is_refused_naming_the_argument():
    """As reset(seed=) takes a seed; bytes were read byte by byte ("108" for b"lqr") or
    named by their repr."""
    run = dict(controller="lqr", episodes=1, horizon=2)
    cases = [
        (dict(seed=2**64), ValueError, "seed must be in [0, 18446744073709551615]; found 18446744073709551616"),
        (dict(seed=-1), ValueError, "seed must be in [0, 18446744073709551615]; found -1"),
        (dict(seed=1.5), TypeError, "seed must be an int (a whole number, as Gymnasium takes one); found 1.5"),
        (dict(controller=b"lqr"), TypeError, "controller must be a controller or a list of them; found bytes b'lqr'"),
        (dict(scenario=bytearray(b"noise")), TypeError, "scenario must be a scenario or a list of them; found"),
    ]
    for what, item in (("controller", b"lqr"), ("scenario", b"noise")):
        why = f"{what} must be a {what} or a list of them (str); found the item {item!r}"
        cases.append(({what: [item]}, TypeError, why))
    for kwargs, kind, why in cases:
        with pytest.raises(kind, match="^" + re.escape(why)):
            cartpole_ddqn.evaluate(**{**run, **kwargs})
    assert len(cartpole_ddqn.evaluate(seed=2**64 - 1, **run)) == 1
