"""Sensitivity inputs refused cleanly (issue 38): variable paths parsed by the config's own
grammar, and objectives that are identically zero or undefined over the run (the pulse never
reaching the wall, a window outside the run) refused naming what to change, in the API
(ObjectiveUndefined, a ConfigError) and the CLI (exit status 2, no traceback)."""

from __future__ import annotations

import copy

import pytest
import tomli_w

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.errors import ConfigError, ObjectiveUndefined

RUN = {"chain": {"diameters_mm": [20.0, 19.0, 18.0, 17.0]},
       "striker": {"velocity": 0.3, "diameter_mm": 8.0},
       "run": {"duration": 3e-4, "sample_interval": 1e-7}}
#: The pulse needs ~0.15 ms to cross 4 beads: a run of 0.03 ms ends before it reaches the wall.
SHORT = {**RUN, "run": {"duration": 3e-5, "sample_interval": 1e-7}}


@pytest.mark.parametrize("path", ["chain.diameters_mm[a]", "chain.diameters_mm[1.5]", "chain.diameters_mm[-1]",
                                  "chain..diameters_mm", "striker.velocity.", "[0]"])
def test_malformed_paths_are_refused_naming_the_grammar(path):
    with pytest.raises(ConfigError, match="not a config path") as info:
        hc.sensitivity(RUN, [path])
    assert info.value.field == "variables" and "chain.diameters_mm[3]" in info.value.message


def test_paths_are_written_as_the_config_writes_them():
    s = hc.sensitivity(RUN, ["chain.diameters_mm", "chain.diameters_mm[2]", "materials.steel.young"])
    assert list(s.gradient) == [f"chain.diameters_mm[{i}]" for i in range(4)] + ["materials.AISI52100.young"]


@pytest.mark.parametrize("objective", ["peak_wall_force", "peak_wall_time", "energy_at_wall", "time_of_flight",
                                       "front_momentum_at_wall", "peak_contact_force[4]"])
def test_an_objective_the_run_never_reaches_is_refused(objective):
    """Before: peak_wall_force = 0 N and every derivative 0, exit 0, no warning."""
    with pytest.raises(ObjectiveUndefined, match="run.duration") as info:
        hc.sensitivity(SHORT, ["striker.velocity"], objective)
    assert info.value.field == "run.duration" and "0.03 ms" in info.value.message


@pytest.mark.parametrize("window, why", [((1e-3, 2e-3), "no sample"), ((0.0, 1e-6), "wall force is 0")])
def test_an_energy_window_outside_the_pulse_is_refused(window, why):
    with pytest.raises(ObjectiveUndefined, match=why) as info:
        hc.sensitivity(RUN, ["striker.velocity"], "energy_at_wall", window=window)
    assert info.value.field == "window"


@pytest.mark.parametrize("args, option", [
    (["--wrt", "chain.diameters_mm[a]"], "--wrt"),
    (["--wrt", "chain.diameters_mm[1.5]"], "--wrt"),
    (["--wrt", "striker.velocity", "--objective", "energy_at_wall", "--window", "1,2"], "--window"),
    (["--wrt", "striker.velocity", "--set", "run.duration=3e-5"], "run.duration"),
])
def test_cli_exit_2_naming_the_option(tmp_path, capsys, args, option):
    path = tmp_path / "run.toml"
    path.write_text(tomli_w.dumps(copy.deepcopy(RUN)))
    assert main(["sensitivity", str(path), *args]) == 2
    err = capsys.readouterr().err
    assert option in err and "Traceback" not in err and "internal error" not in err
