"""A two-worker Dask LocalCluster gives the local results, bit for bit."""

import pytest

import aidnav

from conftest import DRIVE, ROOT

distributed = pytest.importorskip("dask.distributed")


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as c:
            yield c


def test_anomalies_campaign_on_two_workers(client):
    local = aidnav.reproduce("anomalies", runs=20, seed=11)
    assert aidnav.monte_carlo("anomalies", 20, 11, client=client) == local
    assert aidnav.monte_carlo("anomalies", 20, 11, client=client, chunks=7) == local


#: formation-network on a 60 s flight (the quick grid: four cells per run).
SHORT_NETWORK_SWEEP = {
    "duration_s": 60.0,
    "settle_s": 10.0,
    "network": {"sweep": {"latency_s": [0.0, 2.0], "loss_probability": [0.0, 0.3]}},
}


@pytest.mark.parametrize(
    "name, runs, scenario",
    [
        ("consistency", 6, {"epochs": 40}),
        ("group", 5, {"epochs": 40}),
        ("formation", 3, None),
        ("formation-network", 3, SHORT_NETWORK_SWEEP),
    ],
)
def test_every_reproduction_splits_across_two_workers(client, name, runs, scenario):
    local = aidnav.reproduce(name, runs=runs, seed=3, scenario=scenario)
    assert aidnav.monte_carlo(name, runs, 3, scenario=scenario, client=client) == local
    assert aidnav.monte_carlo(name, runs, 3, scenario=scenario, client=client, chunks=runs) == local


def test_a_list_of_configs(client):
    configs = [str(DRIVE), {"platform": "car"}]
    # The second has no data: its error comes back from the worker as the exception.
    with pytest.raises(aidnav.ConfigError, match="missing field `data`"):
        aidnav.monte_carlo(configs, client=client, score=False)
    summaries = aidnav.monte_carlo([DRIVE], client=client, score=False)
    here = aidnav.process(DRIVE, score=False).summary
    strip = lambda s: {k: v for k, v in s["result"].items() if k != "timing_s"}  # noqa: E731
    assert strip(summaries[0]) == strip(here)


#: Two short logs of the zoo.
ZOO_SHORT = [ROOT / "zoo" / "short_car_baseline.toml", ROOT / "zoo" / "short_walk_consumer.toml"]


def test_the_zoo_on_two_workers_is_the_local_zoo(client):
    local = aidnav.zoo(ZOO_SHORT, seeds=[1, 2])
    assert [(e["name"], e["seed"]) for e in local] == [
        ("short_car_baseline", 1),
        ("short_car_baseline", 2),
        ("short_walk_consumer", 1),
        ("short_walk_consumer", 2),
    ]
    assert local[0]["new_user"]["tracking_three_d_m"] < 3.0
    assert aidnav.zoo(ZOO_SHORT, seeds=[1, 2], client=client) == local
