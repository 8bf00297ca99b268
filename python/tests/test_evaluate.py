"""Evaluation: the rows `host-sim eval --json` prints for the same arguments."""

import json

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
