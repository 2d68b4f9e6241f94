"""Reproductions and campaigns: the CLI's summary, chunked == whole."""

import json

import pytest

import aidnav

RUNS, SEED = 12, 20261129


@pytest.fixture(scope="module")
def anomalies():
    return aidnav.reproduce("anomalies", runs=RUNS, seed=SEED)


def test_same_summary_as_the_cli(cli, tmp_path, anomalies):
    cli("reproduce", "anomalies", "--runs", RUNS, "--seed", SEED, "--out", tmp_path, "--quiet")
    assert anomalies == json.loads((tmp_path / "summary.json").read_text())
    assert anomalies["seed"] == SEED and anomalies["scenario"]["runs"] == RUNS
    # Real numbers: anomalies hurt the plain filter, the developed scheme less.
    assert anomalies["rms"]["developed"] < anomalies["rms"]["kf_plain"]


@pytest.mark.parametrize("chunks", [1, 5, RUNS])
def test_chunked_campaign_is_bit_identical(anomalies, chunks):
    assert aidnav.monte_carlo("anomalies", RUNS, SEED, chunks=chunks) == anomalies


def test_a_scenario_dict_and_its_errors(tmp_path):
    s = aidnav.reproduce("consistency", runs=3, seed=1, scenario={"epochs": 50})
    assert s["scenario"]["epochs"] == 50 and s["scenario"]["runs"] == 3
    with pytest.raises(aidnav.ConfigError, match="<scenario dict>:1: epochs"):
        aidnav.reproduce("consistency", scenario={"epochs": -5})
    path = tmp_path / "s.toml"
    path.write_text("runs = 4\nplatform_typo = 1\n")
    with pytest.raises(aidnav.ConfigError, match=f"{path}:2: platform_typo"):
        aidnav.reproduce("anomalies", scenario=path)
    with pytest.raises(aidnav.AidnavError, match="unknown experiment"):
        aidnav.reproduce("nope")


def test_chunks_that_do_not_cover_the_campaign_are_refused():
    c = aidnav.Campaign("anomalies", runs=4, seed=2)
    part = c.run_chunk(0, 2)
    with pytest.raises(aidnav.AidnavError, match="the chunks hold 2 runs, the campaign has 4"):
        c.finish([part])
    with pytest.raises(aidnav.AidnavError, match="not within the campaign's 4 runs"):
        c.run_chunk(3, 9)
    assert all(aidnav.Campaign(name, runs=2).splits for name in aidnav.experiment_names())
