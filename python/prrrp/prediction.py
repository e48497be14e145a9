"""Torque predictions at the rows of a measured log, scored against the measured torque.

Identification fits the processed (low-passed, trimmed) log; scoring against that torque
would score a model against our own filtered version of the measurement, moving with
``--cutoff`` and flattering every model. So every torque error prrrp reports is against
the torque **as measured**, at the rows it was measured: the model is evaluated on the
untrimmed processed signals and interpolated to every row's time stamp; rows in the
filter's edge transient and repeated time stamps are predicted but not scored, and
counted. A log that gives q̇ and q̈ is evaluated at its rows as they are.

Design: docs/design/torque-scoring.md.

>>> grid = prrrp.prediction.prepare(raw, model.preprocessing["settings"])  # doctest: +SKIP
>>> tau_hat = grid.predict(model)          # (rows, n), at every row of the log
>>> grid.errors(tau_hat)["percent"]        # per joint, % of the measured torque's RMS
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from prrrp._prrrp import Dataset, IdentifiedModel, InvalidInputError, preprocess_log
from prrrp.measurements import PREPROCESS_KEYS, measurements_to_dataset


@dataclasses.dataclass
class LogGrid:
    """A measured log prepared for predictions at its rows (see the module docs).

    ``t`` (S,) s, the log's time stamps; ``measured`` (S, n) its torque column as read (None
    when the log has none); ``filtered`` (S, n) the low-passed torque identification fits,
    at the rows (None when not processed); ``edge`` and ``repeated`` (S,) bool, the rows not
    scored and why; ``processed`` the whole-log signals the model is evaluated on;
    ``data`` the data set identification would use (trimmed); ``report`` what the
    preprocessing did (None when q̇, q̈ were given)."""

    t: np.ndarray
    measured: np.ndarray | None
    filtered: np.ndarray | None
    edge: np.ndarray
    repeated: np.ndarray
    processed: Dataset
    data: Dataset
    report: dict[str, Any] | None
    #: "log" (measurements as read: scored against the measured torque) or "dataset" (a
    #: ready Dataset: scored against its own τ, whatever made it).
    source: str = "log"
    #: Predictions already made on this grid, by model (an IdentifiedModel is immutable):
    #: the report and the method comparison ask for the same model's several times.
    _predicted: dict[int, tuple[IdentifiedModel, np.ndarray]] = dataclasses.field(
        default_factory=dict, repr=False, compare=False
    )
    #: The measured torque's noise (:func:`noise_rms`, two medians over the whole log):
    #: the same for every model scored here, computed once.
    _noise: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)

    @property
    def scored(self) -> np.ndarray:
        """(S,) bool: the rows every error is computed over."""
        return ~(self.edge | self.repeated)

    @property
    def span(self) -> tuple[float, float]:
        """First and last scored time stamps, s."""
        t = self.t[self.scored]
        return (float(t[0]), float(t[-1])) if len(t) else (float("nan"), float("nan"))

    def predict(self, model: IdentifiedModel) -> np.ndarray:
        """``model``'s torque at every row of the log, (S, n) N·m or N."""
        hit = self._predicted.get(id(model))
        if hit is None or hit[0] is not model:
            p = self.processed
            tau = np.asarray(model.predict(p.q, p.qd, p.qdd))
            hit = (model, _at_rows(np.asarray(p.t), tau, self.t))
            self._predicted[id(model)] = hit
        return hit[1].copy()

    def errors(self, predicted: np.ndarray) -> dict[str, Any]:
        """Per joint over the scored rows: ``rms`` of measured − predicted (N·m, N),
        ``tau_rms`` of the measured torque, ``percent`` = 100·rms/tau_rms, ``noise_rms``
        the measured torque's noise (:func:`noise_rms`, over the rows with a new time
        stamp): an error near it is as small as the log can show; beside them, labelled,
        ``filtered_rms`` and ``filtered_percent`` against the low-passed torque
        identification fits (None when not processed); ``rows`` scored, ``rows_total``,
        ``edge_rows``, ``repeated_rows``, ``span`` (s)."""
        if self.measured is None:
            raise InvalidInputError("the log has no measured torque to score against")
        k = self.scored
        rms = _rms(self.measured[k] - predicted[k])
        ref = _rms(self.measured[k])
        out: dict[str, Any] = {
            "rms": rms,
            "tau_rms": ref,
            "percent": _percent(rms, ref),
            "noise_rms": self._noise_rms(),
            "filtered_rms": None,
            "filtered_percent": None,
            "rows": int(k.sum()),
            "rows_total": len(self.t),
            "edge_rows": int(self.edge.sum()),
            "repeated_rows": int((self.repeated & ~self.edge).sum()),
            "span": self.span,
        }
        if self.filtered is not None:
            f = _rms(self.filtered[k] - predicted[k])
            out["filtered_rms"] = f
            out["filtered_percent"] = _percent(f, _rms(self.filtered[k]))
        return out

    def _noise_rms(self) -> np.ndarray:
        if self._noise is None:
            assert self.measured is not None
            self._noise = noise_rms(self.measured[~self.repeated])
        return self._noise.copy()

    def describe(self) -> str:
        """One line: which rows are scored, and why the others are not."""
        n, k = len(self.t), int(self.scored.sum())
        parts = []
        if self.edge.any():
            parts.append(f"{int(self.edge.sum())} in the filter's edge transient")
        if (self.repeated & ~self.edge).any():
            parts.append(
                f"{int((self.repeated & ~self.edge).sum())} repeating the previous time stamp"
            )
        a, b = self.span
        why = f"; not scored: {', '.join(parts)}" if parts else ""
        what = "; against the data set's own τ" if self.source == "dataset" else ""
        return f"{k} of {n} rows, t = {a:.6g}..{b:.6g} s{why}{what}"


#: Σ of the squared coefficients of a third difference (1, −3, 3, −1).
_THIRD_DIFFERENCE_GAIN = 20.0


def noise_rms(tau: np.ndarray) -> np.ndarray:
    """Per column of ``tau`` (S, n), sampled in order: the RMS of its white noise,
    estimated from the third differences (which cancel a motion smooth over four samples
    and multiply white noise's variance by 20) by their median absolute deviation (robust
    to the few large ones of a jump). Motion faster than a few samples counts as noise:
    at low sample rates this is an upper bound. NaN with fewer than 8 rows."""
    tau = np.asarray(tau, dtype=float)
    if tau.ndim != 2 or len(tau) < 8:
        return np.full(tau.shape[-1] if tau.ndim == 2 else 1, np.nan)
    d = np.diff(tau, 3, axis=0)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(_THIRD_DIFFERENCE_GAIN)


def _rms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(np.asarray(x) ** 2, axis=0))


def _percent(rms: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.where(ref > 0, 100.0 * rms / np.where(ref > 0, ref, 1.0), np.nan)


def _at_rows(t_grid: np.ndarray, values: np.ndarray, t_rows: np.ndarray) -> np.ndarray:
    """Columns of ``values`` (on the increasing ``t_grid``) interpolated linearly to
    ``t_rows`` (held at the end values outside the grid)."""
    out = np.empty((len(t_rows), values.shape[1]))
    for j in range(values.shape[1]):
        out[:, j] = np.interp(t_rows, t_grid, values[:, j])
    return out


def _repeats(t: np.ndarray) -> np.ndarray:
    rep = np.zeros(len(t), dtype=bool)
    rep[1:] = t[1:] == t[:-1]
    return rep


def prepare(
    raw: Mapping[str, np.ndarray] | Dataset,
    settings: Mapping[str, Any] | None = None,
    *,
    identified: tuple[Dataset, dict[str, Any] | None] | None = None,
) -> LogGrid:
    """A measured log (``prrrp.read_measurements``'s dict) prepared for predictions at its
    rows, with the preprocessing ``settings`` of identification (keys of
    ``prrrp.preprocess_log``; None/missing = its defaults). A ``Dataset`` is taken as it is
    (its rows and its τ are then what is scored). ``identified``: the (data set, report)
    identification made from this log with these settings, not made again. Raises what
    the preprocessing raises."""
    if isinstance(raw, Dataset):
        t = np.asarray(raw.t)
        none = np.zeros(len(t), dtype=bool)
        tau = np.asarray(raw.tau)
        return LogGrid(t, tau, None, none, none.copy(), raw, raw, None, "dataset")
    t = np.asarray(raw["t"], dtype=float)
    measured = np.asarray(raw["tau"], dtype=float) if "tau" in raw else None
    tau = measured if measured is not None else np.zeros_like(np.asarray(raw["q"]))
    log = {**raw, "tau": tau}
    settings = {k: v for k, v in dict(settings or {}).items() if k in PREPROCESS_KEYS}
    if identified is not None:
        data, report = identified
    else:
        data, report = measurements_to_dataset(log, settings)
    if report is None:  # q̇ and q̈ given: evaluated at the rows as they are
        none = np.zeros(len(t), dtype=bool)
        return LogGrid(t, measured, None, none, _repeats(t), data, data, None)
    whole = {**settings, "cutoff_hz": report["cutoff_hz"], "rate_hz": report["rate_hz"]}
    whole.pop("decimate_to_hz", None)
    whole["trim_s"] = 0.0
    processed, _ = preprocess_log(t, log["q"], tau, qd=log.get("qd"), **whole)
    td = np.asarray(data.t)
    # A hair of slack: grid times are t0 + i/rate, rounded differently from the rows'.
    eps = 1e-9 * max(1.0, float(np.abs(t).max()))
    edge = (t < td[0] - eps) | (t > td[-1] + eps)
    filtered = None
    if measured is not None:
        filtered = _at_rows(np.asarray(processed.t), np.asarray(processed.tau), t)
    return LogGrid(t, measured, filtered, edge, _repeats(t), processed, data, dict(report))


def recorded_settings(model: IdentifiedModel) -> dict[str, Any]:
    """The preprocessing settings a model was identified with (its record), checked: a
    value of the wrong type (a hand-edited model.json) is a ValueError naming it."""
    pre = model.preprocessing
    if pre is None or pre == {}:
        return {}
    if not isinstance(pre, dict):
        raise InvalidInputError(
            f"the model's 'preprocessing' is a {type(pre).__name__}, not an object"
        )
    settings = pre.get("settings") or {}
    if not isinstance(settings, dict):
        raise InvalidInputError(
            f"the model's preprocessing 'settings' is a {type(settings).__name__}, not an object"
        )
    return check_settings(settings, "the model's preprocessing setting")


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


#: Type of each preprocessing setting: a check and what it should be.
_SETTING_TYPES: dict[str, tuple[Any, str]] = {
    "rate_hz": (_is_number, "a number (Hz)"),
    "cutoff_hz": (_is_number, "a number (Hz)"),
    "order": (lambda v: isinstance(v, int) and not isinstance(v, bool), "an integer"),
    "filter_torque": (lambda v: isinstance(v, bool), "true or false"),
    "trim_s": (_is_number, "a number (s)"),
    "decimate_to_hz": (_is_number, "a number (Hz)"),
    "max_gap_s": (_is_number, "a number (s)"),
}


def check_settings(settings: Mapping[str, Any], what: str) -> dict[str, Any]:
    """``settings`` with every known key's value type-checked (None = the default); raises
    ValueError naming the first bad one. Unknown keys are dropped."""
    out = {}
    for key, value in settings.items():
        if key not in _SETTING_TYPES or value is None:
            continue
        ok, expected = _SETTING_TYPES[key]
        if not ok(value):
            raise InvalidInputError(f"{what} '{key}' is {value!r}; it must be {expected}")
        out[key] = value
    return out
