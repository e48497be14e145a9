"""The main job for any robot, as functions: load a robot file, identify it from a log,
and report — what ``prrrp identify --robot`` runs, for notebook users.

>>> robot = prrrp.load_robot("panda.urdf", tip="panda_link8",
...                          friction="viscous+coulomb+offset")      # doctest: +SKIP
>>> run = prrrp.identify_measurements(robot, prrrp.read_measurements("log.csv", robot))
...                                                                   # doctest: +SKIP
>>> run.model.save("model.json"); run.report("report_dir")           # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np

from prrrp import model_report
from prrrp._prrrp import Dataset, IdentifiedModel, SerialChain, identify
from prrrp.measurements import PREPROCESS_KEYS, measurements_to_dataset

#: Methods of :func:`identify_measurements`, in the order ``--method all`` runs them.
METHODS = ("ls", "wls", "rls", "adaline", "hopfield", "ekf", "physical")


def load_robot(
    path: str | os.PathLike[str],
    *,
    base: str | None = None,
    tip: str | None = None,
    friction: str | list[str] | None = None,
    coulomb_scale: float = 0.0,
) -> SerialChain:
    """A robot from a ``.urdf`` (the chain from link ``base`` to link ``tip``) or ``.toml``
    file, with the friction terms to identify (``"viscous+coulomb+offset"``, a list of
    them, or None for the file's own) and the Coulomb speed scale (rad/s; 0 = exact sign)."""
    robot = SerialChain.from_file(path, base=base, tip=tip)
    if friction is not None:
        terms = friction if isinstance(friction, str) else "+".join(friction)
        robot = robot.with_friction(terms or None, None, coulomb_smoothing=coulomb_scale)
    return robot


@dataclasses.dataclass
class Identification:
    """The result of :func:`identify_measurements`: the model, the data set it was
    identified from, what the preprocessing did (None when q̇, q̈ were given) and the
    Coulomb speed-scale search (None when not run)."""

    model: IdentifiedModel
    data: Dataset
    log_report: dict[str, Any] | None
    coulomb: dict[str, Any] | None

    def report(
        self,
        directory: str | os.PathLike[str],
        validation: Dataset | None = None,
        **kwargs: Any,
    ) -> list[Path]:
        """Writes ``report.md`` and the figures into the existing folder ``directory``."""
        return model_report.write_report(
            self.model,
            directory,
            self.data,
            validation=validation,
            log_report=self.log_report,
            coulomb=self.coulomb,
            **kwargs,
        )


def with_coulomb_scale(robot: SerialChain, v_s: float) -> SerialChain:
    """The robot with Coulomb speed scale ``v_s`` (rad/s; 0 = exact sign)."""
    terms = "+".join(robot.friction) or None
    return robot.with_friction(terms, robot.friction_params, coulomb_smoothing=v_s)


def identify_measurements(
    robot: SerialChain,
    raw: dict[str, np.ndarray] | Dataset,
    method: str = "ls",
    *,
    coulomb_scale: str | float = "auto",
    preprocessing: dict[str, Any] | None = None,
    **settings: Any,
) -> Identification:
    """Identifies ``robot`` from measurements (``prrrp.read_measurements``'s dict, or a
    ready ``Dataset``): preprocessing when q̇ and q̈ are not given (``preprocessing``:
    settings of ``prrrp.preprocess_log``, e.g. ``{"cutoff_hz": 5.0}``), the Coulomb speed
    scale (``"auto"``: chosen from the data when the robot has a Coulomb term, see
    ``SerialChain.coulomb_scale``; a number: that scale, 0 = exact sign), then
    ``prrrp.identify(robot, data, method, **settings)``. The model records the
    preprocessing settings and report and the speed-scale search, so ``prrrp predict``
    can treat new logs the same way."""
    preprocessing = {k: v for k, v in (preprocessing or {}).items() if v is not None}
    unknown = sorted(set(preprocessing) - set(PREPROCESS_KEYS))
    if unknown:
        raise TypeError(f"unknown preprocessing settings {unknown}; valid: {PREPROCESS_KEYS}")
    if isinstance(raw, Dataset):
        data, log_report = raw, None
    else:
        data, log_report = measurements_to_dataset(raw, preprocessing)
    coulomb = None
    if isinstance(coulomb_scale, str):
        if coulomb_scale != "auto":
            raise ValueError(f"coulomb_scale must be 'auto' or a number, got {coulomb_scale!r}")
        if "coulomb" in robot.friction:
            coulomb = robot.coulomb_scale(data)
            robot = with_coulomb_scale(robot, coulomb["chosen"])
    else:
        v_s = float(coulomb_scale)
        if not (np.isfinite(v_s) and v_s >= 0):
            raise ValueError(f"coulomb_scale must be finite and >= 0 rad/s, got {v_s}")
        robot = with_coulomb_scale(robot, v_s)
    record = {"settings": preprocessing, "report": log_report, "coulomb_scale": coulomb}
    model = identify(robot, data, method, preprocessing=record, **settings)
    return Identification(model, data, log_report, coulomb)
