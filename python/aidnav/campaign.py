"""Monte Carlo campaigns, here or on a Dask cluster.

A reproduction's campaign is split into chunks of runs. Run k always draws
stream k of the master seed (ChaCha8, ``set_stream(k)``) whoever computes
it, and the chunks are combined in run order by the same code that
combines a local campaign, so the summary is bit-identical to the local one
whatever the number of workers and the chunking. Every reproduction
splits (the library's ``run_range`` and ``finish`` of each experiment).
"""

from __future__ import annotations

import math
import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

from . import _aidnav

Spec = Tuple[str, Optional[Union[str, Dict[str, Any]]], Optional[str], Optional[int], Optional[int]]

#: Chunks per worker on a cluster (a few, so a slow worker does not hold up the end).
CHUNKS_PER_WORKER = 4


def _campaign(spec: Spec) -> "_aidnav.Campaign":
    name, scenario, text, runs, seed = spec
    if text is not None:
        return _aidnav.Campaign(name, None, runs, seed, scenario_text=text, origin=scenario)
    return _aidnav.Campaign(name, scenario, runs, seed)


def _run_chunk(spec: Spec, start: int, end: int) -> bytes:
    """A worker's task: runs start..end of the campaign, as bytes."""
    return _campaign(spec).run_chunk(start, end)


def _run_process(config: Any, score: bool) -> Dict[str, Any]:
    """A worker's task: one log processed, its summary."""
    from . import process

    return process(config, score=score, as_frame=False).summary


def chunk_bounds(runs: int, chunks: int) -> List[Tuple[int, int]]:
    """``runs`` split into at most ``chunks`` contiguous ranges, in order."""
    chunks = max(1, min(chunks, runs))
    size = math.ceil(runs / chunks) if runs else 0
    return [(a, min(a + size, runs)) for a in range(0, runs, size)] if runs else []


def _spec(name: str, scenario: Any, runs: Optional[int], seed: Optional[int]) -> Spec:
    if scenario is None or isinstance(scenario, Mapping):
        return (name, None if scenario is None else dict(scenario), None, runs, seed)
    path = os.fspath(scenario)
    with open(path, encoding="utf-8") as f:  # read here: workers need not see the file
        text = f.read()
    return (name, path, text, runs, seed)


def _workers(client: Any) -> int:
    return max(1, len(client.scheduler_info().get("workers", {})))


def _gather(client: Any, futures: list) -> list:
    try:
        return client.gather(futures)
    except KeyboardInterrupt:
        client.cancel(futures)
        raise


def monte_carlo(
    target: Union[str, Sequence[Any]],
    runs: Optional[int] = None,
    seed: Optional[int] = None,
    scenario: Any = None,
    client: Any = None,
    *,
    chunks: Optional[int] = None,
    score: bool = True,
) -> Union[Dict[str, Any], List[Dict[str, Any]]]:
    """Run a Monte Carlo campaign, locally or on a Dask cluster.

    ``target`` is a reproduction's name (:func:`aidnav.experiment_names`;
    ``runs``, ``seed`` and ``scenario`` as in :func:`aidnav.reproduce`): the
    result is its ``summary.json`` as a dict, bit-identical to
    :func:`aidnav.reproduce` whatever ``client`` and ``chunks``. Or a list of
    ``process`` configurations (TOML paths or dicts: a tuning sweep, a
    fleet of logs): the result is the list of their summaries, in order.

    ``client`` is a ``dask.distributed.Client`` (None: here, all cores);
    ``chunks`` the number of chunks the runs are split into (default: four
    per worker; here, one call for the whole campaign unless ``chunks`` is
    given). Ctrl-C stops the work here (the Rust loops look at a
    cancellation flag between runs) and cancels a cluster's futures. On a real cluster every worker needs this
    package installed (``pip install ./python``) and, for ``process``
    configurations, the data files at the same paths.
    """
    if not isinstance(target, str):
        configs = [c if isinstance(c, Mapping) else os.fspath(c) for c in target]
        if client is None:
            return [_run_process(c, score) for c in configs]
        futures = [client.submit(_run_process, c, score, pure=False) for c in configs]
        return _gather(client, futures)
    spec = _spec(target, scenario, runs, seed)
    campaign = _campaign(spec)
    if client is None:
        if chunks is None:
            return campaign.summary()
        bounds = chunk_bounds(campaign.runs, chunks)
        parts = [campaign.run_chunk(a, b) for a, b in bounds]
    else:
        bounds = chunk_bounds(campaign.runs, chunks or CHUNKS_PER_WORKER * _workers(client))
        futures = [client.submit(_run_chunk, spec, a, b, pure=False) for a, b in bounds]
        parts = _gather(client, futures)
    return campaign.finish(list(parts))


def _zoo_entry(scenario: Any, seed: Optional[int]) -> Dict[str, Any]:
    """A worker's task: one scenario simulated, processed and scored."""
    return _aidnav.zoo_entry(scenario, seed)


def zoo(
    scenarios: Sequence[Any],
    seeds: Optional[Sequence[int]] = None,
    client: Any = None,
) -> List[Dict[str, Any]]:
    """The zoo as a campaign: every scenario (TOML paths or dicts) × every
    seed (None: each scenario's own) simulated, processed with its new-user
    configuration and with the matched noise model, and scored against its
    truth — one dict per (scenario, seed), in that order, the entries of
    ``aidnav zoo``'s ``summary.json``. ``client``: a
    ``dask.distributed.Client`` (None: here, one after the other). Each
    entry depends only on its scenario and seed, so a cluster gives the
    local result bit for bit. On a real cluster every worker needs this
    package and, for paths, the scenario files at the same paths."""
    items = [
        (s if isinstance(s, Mapping) else os.fspath(s), seed)
        for s in scenarios
        for seed in (list(seeds) if seeds is not None else [None])
    ]
    if client is None:
        return [_zoo_entry(s, seed) for s, seed in items]
    futures = [client.submit(_zoo_entry, s, seed, pure=False) for s, seed in items]
    return _gather(client, futures)
