"""Columns of numpy arrays as pandas DataFrames when pandas is installed,
as plain dicts otherwise."""

from __future__ import annotations

from typing import Any, Dict, List, Mapping, Optional

import numpy as np

try:  # pandas is optional
    import pandas as _pd
except ImportError:  # pragma: no cover - exercised by the no-pandas test
    _pd = None

Columns = Dict[str, np.ndarray]


def have_pandas() -> bool:
    """Whether pandas can be imported (and tables are DataFrames)."""
    return _pd is not None


def want_frame(as_frame: Optional[bool]) -> bool:
    """Resolve an ``as_frame`` argument: None means "when pandas is installed"."""
    if as_frame is None:
        return _pd is not None
    if as_frame and _pd is None:
        raise ImportError("as_frame=True needs pandas (pip install pandas)")
    return bool(as_frame)


def table(columns: Mapping[str, Any], as_frame: Optional[bool] = None, attrs: Optional[dict] = None):
    """``columns`` as a DataFrame (with ``attrs``) or as a dict of arrays."""
    if want_frame(as_frame):
        frame = _pd.DataFrame(dict(columns))
        if attrs:
            frame.attrs.update(attrs)
        return frame
    return dict(columns)


def records(rows: List[Mapping[str, Any]], as_frame: Optional[bool] = None):
    """A list of JSON objects (a summary's table) as a DataFrame, or as a dict
    of arrays (one per key, in first-seen order; None becomes NaN)."""
    keys: List[str] = []
    for r in rows:
        for k in r:
            if k not in keys:
                keys.append(k)
    if want_frame(as_frame):
        return _pd.DataFrame.from_records(list(rows), columns=keys)
    out: Columns = {}
    for k in keys:
        values = [r.get(k) for r in rows]
        if all(v is None or isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            out[k] = np.array([np.nan if v is None else v for v in values], dtype=float)
        else:
            out[k] = np.array(values, dtype=object)
    return out


def columns_of(data: Any, what: str) -> Columns:
    """A DataFrame, a dict of array-likes or a numpy structured array as a
    dict of 1-D numpy arrays (what the extension takes)."""
    if data is None:
        raise TypeError(f"{what}: no data")
    if _pd is not None and isinstance(data, _pd.DataFrame):
        return {str(c): data[c].to_numpy() for c in data.columns}
    if isinstance(data, np.ndarray) and data.dtype.names:
        return {n: np.asarray(data[n]) for n in data.dtype.names}
    if isinstance(data, Mapping):
        return {str(k): np.asarray(v) for k, v in data.items()}
    raise TypeError(
        f"{what}: a pandas DataFrame, a dict of arrays or a structured array, not {type(data).__name__}"
    )
