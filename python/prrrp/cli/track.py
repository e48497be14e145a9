"""``prrrp track DATA [--robot ROBOT] [--model PRIOR.json] [--payload] --out DIR``: the log fed
to ``prrrp.OnlineIdentifier`` one row at a time, as it would be while the arm runs →
``DIR/model.json`` (the estimate at the end of the data), ``DIR/payload.json`` (payload
mode), ``DIR/estimates.csv``, ``DIR/prediction.csv``, ``DIR/track.png`` and
``DIR/report.md``."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

import prrrp
from prrrp import csvio, drives, measurements, outdir, workflow
from prrrp import payload as payloads
from prrrp.cli import common
from prrrp.cli.predict import load_model
from prrrp.measurements import median_step, read_measurements
from prrrp.prediction import noise_rms

#: ``prrrp track --help``.
HELP = "identify while the arm runs: a log fed one sample at a time"
DESCRIPTION = (
    "Feeds DATA (a CSV t, q1..qN, tau1..tauN, optional qd1..qdN, or a ROS 2 "
    "bag; motor currents i1..iN with --drive-gains) row by row to the online "
    "identifier, causally (no row sees a later one), and "
    "writes DIR/model.json (the estimate at the end of the data, predictable with "
    "`prrrp predict`), DIR/estimates.csv (t and each estimated parameter with σ over "
    "time), DIR/prediction.csv (t, tau1..tauN: the one-step-ahead prediction of each "
    "row from the estimate before it), DIR/track.png and DIR/report.md. With --payload "
    "(needs --model): only the 10 inertial parameters of a payload at the tip link are "
    "tracked on the prior arm, and DIR/payload.json gives its mass (kg), centre of mass "
    "(m, tip frame) and inertia about it (kg·m²), each with σ."
)

METHODS = ("rls", "ekf", "adaline", "hopfield")

#: At most this many rows of estimates.csv (evenly spaced; the last row always kept).
MAX_ESTIMATE_ROWS = 5000


def add_parser(sub: Any) -> None:
    p = common.add_command(sub, "track", run, help=HELP, description=DESCRIPTION)
    p.add_argument("data", metavar="DATA", help="measurement CSV file or ROS 2 bag")
    common.add_robot_arguments(p, default="the robot of --model, else paper")
    p.add_argument(
        "--friction",
        metavar="TERMS",
        default="viscous,coulomb,offset",
        help="friction terms with --robot, comma-separated from viscous, coulomb, offset, or "
        "'none' (default: viscous,coulomb,offset)",
    )
    p.add_argument(
        "--coulomb-scale",
        metavar="auto|V",
        help="with --robot: speed scale v_s (rad/s) of the smooth Coulomb term "
        "fc·tanh(q̇/v_s), 0 = exact sign. auto (default): chosen online, causally, among "
        "0 and 0.001, 0.002, 0.004, …, 0.256 rad/s (an octave apart) by the one-step-ahead "
        "torque error of an RLS of each (whatever the method) "
        "from 5 s to 10 s after the first row (until then all run; the estimates before "
        "the choice are the exact sign's). --model carries the scale `prrrp identify` chose",
    )
    p.add_argument(
        "--model",
        metavar="PRIOR.json",
        help="start from this identified model (its robot, estimate and covariance); "
        "needed by --payload (default: none, the robot file's chain from no knowledge)",
    )
    p.add_argument("--method", choices=METHODS, default="rls", help="default: rls")
    p.add_argument(
        "--payload",
        action="store_true",
        help="track only a payload at the tip link on the arm of --model",
    )
    p.add_argument(
        "--forgetting",
        type=common.number,
        metavar="SECONDS",
        help="memory: data older than this weigh less than 1/e (rls: directional, ekf: a "
        "random walk of the parameters; default: none, changes are followed through the "
        "change detection)",
    )
    p.add_argument(
        "--no-change-detection",
        action="store_true",
        help="do not open the covariance when the one-step-ahead errors jump",
    )
    p.add_argument(
        "--cutoff",
        type=common.number,
        metavar="HZ",
        help="bandwidth of the causal filtering, below the Nyquist frequency of the rows "
        "(default: 10 Hz, lowered once after the first second of filtered rows to where "
        "the positions' sensor noise, from their third differences, leaves the "
        "accelerations within a tenth of their RMS (0.3 rad/s² for a joint that moves "
        "less), at most to 2.5 Hz, the one-step-ahead predictions' tracker with it; the "
        "whole-arm ekf, whose filter measures q and q̇, lowers only the tracker)",
    )
    p.add_argument(
        "--prior-width",
        type=common.number,
        default=3.0,
        metavar="W",
        help="the prior's covariance times W² (default 3)",
    )
    p.add_argument(
        "--ekf-noise",
        type=common.number,
        default=None,
        metavar="F",
        help="ekf: factor on the measurement noise of positions (1e-3 rad) and velocities "
        "(1e-2 rad/s) (default 1; not used with --payload, whose filter measures the "
        "torque the arm does not explain, with the running torque noise)",
    )
    common.add_drive_gains_argument(
        p, "as the log of --model was converted, else none: the log has torques tau1..tauN"
    )
    common.add_motor_side_argument(p, "as the log of --model was, else joint side")
    common.add_topic_argument(p)
    common.add_out_argument(p)


def _read(
    args: argparse.Namespace, robot: prrrp.SerialChain, prior: prrrp.IdentifiedModel | None
) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    """The log on the joint side, and how it was converted (``drives.record``): motor
    currents through ``--drive-gains`` and motor-side data through ``--motor-side``, or
    else as the log ``--model`` was identified from (its gains apply only to a log of
    currents, as for ``prrrp predict``)."""
    recorded = drives.recorded(prior) if prior is not None else {}
    gains = recorded.get("drive_gains")
    explicit = args.drive_gains is not None
    if explicit:
        gains = drives.parse_gains(args.drive_gains, robot.dof)
    motor_side = bool(args.motor_side or recorded.get("motor_side", False))
    raw = read_measurements(
        args.data,
        robot,
        topic=args.topic,
        need_tau=explicit or gains is None,
        drive_gains=gains,
        motor_side=motor_side,
    )
    if "tau" not in raw:
        n = robot.dof
        raise common.CliError(f"{args.data}: no torques tau1..tau{n} (nor motor currents i1..i{n})")
    return raw, drives.record(gains, motor_side)


def _record_drives(path: Path, record: dict[str, Any]) -> None:
    """Adds to the model file how the log was converted, as `prrrp identify` records it,
    so that `prrrp predict` converts new logs the same way."""
    doc = json.loads(path.read_text(encoding="utf-8"))
    doc.setdefault("preprocessing", {})["drives"] = record
    csvio.write_text_atomic(path, json.dumps(doc, indent=2))


def _check_rate(t: np.ndarray, cutoff: float, forgetting: float | None) -> None:
    """CliError for a cut-off the log's rows cannot carry (at or above their Nyquist
    frequency: every row would restart the causal filtering, and nothing would be learned)
    or a memory that forgets everything between two rows."""
    dt = median_step(t)
    if dt is None:
        # `identify` refuses it alike: rows that share a time stamp are one sample.
        raise common.CliError(
            f"every one of the log's {len(t)} rows has the time stamp {t[0]:g} s: rows that "
            "share a time stamp are one sample; give each sample its own time, in s"
        )
    # A relative margin: 100 Hz time stamps of 0.01·k s have a median step 2e-16 under
    # 0.01 s, and a --cutoff of exactly 50 Hz passed.
    if cutoff >= 0.5 / dt * (1 - 1e-9):
        raise common.CliError(
            f"--cutoff {cutoff:g} Hz is not below the Nyquist frequency of the log's rows "
            f"({0.5 / dt:.3g} Hz: a row every {dt:.3g} s); give a lower --cutoff"
        )
    if forgetting is not None and math.exp(-dt / forgetting) < 1e-12:
        raise common.CliError(
            f"--forgetting {forgetting:g} s forgets everything between two rows (a row every "
            f"{dt:.3g} s); give a memory that spans many rows"
        )


def _check_settling(t: np.ndarray, cutoff: float | None) -> None:
    """CliError for a --cutoff whose start-up transient (SETTLING_PERIODS/cutoff s, the
    online identifier's own rule) outlasts the whole log: no row could update the estimate
    (1e-300 Hz ran to the end and wrote the starting model). The default cut-off on a log
    that short is only warned of, after the run."""
    if cutoff is None:
        return
    span = float(t[-1] - t[0])
    settling = prrrp.SETTLING_PERIODS / cutoff
    if settling > span:
        raise common.CliError(
            f"--cutoff {cutoff:g} Hz settles in {settling:.3g} s "
            f"({prrrp.SETTLING_PERIODS:g}/cutoff), longer than the log ({span:.3g} s): no row "
            "would update the estimate; give a higher --cutoff"
        )


def _positive(name: str, v: float | None) -> None:
    # `common.number` has made it finite.
    if v is not None and not v > 0:
        raise common.CliError(f"{name} must be > 0, got {v}")


def run(args: argparse.Namespace) -> int:
    _positive("--forgetting", args.forgetting)
    _positive("--cutoff", args.cutoff)
    common.check_factor("--prior-width", args.prior_width)
    common.check_factor("--ekf-noise", args.ekf_noise)
    if args.ekf_noise is not None and (args.method != "ekf" or args.payload):
        raise common.CliError(
            "--ekf-noise sets the whole-arm ekf's measurement noise: it needs --method ekf "
            "without --payload"
        )
    if args.payload and not args.model:
        raise common.CliError("--payload tracks a load on a known arm: give its model with --model")
    coulomb_scale = common.coulomb_scale(args.coulomb_scale)
    fixed = coulomb_scale not in (None, "auto")
    prior = load_model(args.model) if args.model else None
    if prior is not None:
        if args.robot:
            raise common.CliError("--model carries its robot; --robot is not needed with it")
        if args.coulomb_scale is not None:
            raise common.CliError(
                "--model carries its Coulomb scale (chosen by `prrrp identify`); "
                "--coulomb-scale is for --robot"
            )
        robot = prior.robot
    else:
        robot = workflow.load_robot(
            args.robot or common.DEFAULT_ROBOT,
            base=args.base,
            tip=args.tip,
            friction=common.friction_terms(args.friction),
            coulomb_scale=coulomb_scale if fixed else 0.0,
        )
    outdir.check(args.out)
    raw, record = _read(args, robot, prior)
    online = prrrp.OnlineIdentifier(
        None if prior is not None else robot,
        prior=prior,
        method=args.method,
        payload=args.payload,
        forgetting=args.forgetting,
        change_detection=not args.no_change_detection,
        cutoff_hz=args.cutoff,
        prior_width=args.prior_width,
        ekf_noise=1.0 if args.ekf_noise is None else args.ekf_noise,
        coulomb_scale=None if prior is not None or fixed else "auto",
    )
    _check_rate(raw["t"], online.settings["cutoff_hz"], args.forgetting)
    _check_settling(raw["t"], args.cutoff)
    run_ = track(online, raw, common.Progress())
    if online.counts[1] == 0 and prior is None:
        # The starting parameters are zeros, not a model: it was written, with every
        # torque predicted 0 and exit 0, and `prrrp payload` went on to read a 4.6 kg load
        # off it.
        raise common.CliError(
            f"no row updated the estimate: {_nothing_learned(online, raw)}; with no prior "
            "(--model) there is no model to write. Give a longer log with the torques, or a "
            "prior with --model"
        )
    model = online.estimate()
    payload = online.payload()

    def build(tmp: Path) -> list[Path]:
        written = [tmp / "model.json", tmp / "estimates.csv", tmp / "prediction.csv"]
        model.save(tmp / "model.json")
        if record:
            _record_drives(tmp / "model.json", record)
        names = online.parameter_names
        header = ["t", *names, *(f"sigma_{n}" for n in names)]
        csvio.write_text_atomic(tmp / "estimates.csv", _csv(header, run_["estimates"]))
        n = online.dof
        pred = np.column_stack([raw["t"], run_["prediction"]])
        header = ["t", *(f"tau{j + 1}" for j in range(n))]
        csvio.write_text_atomic(tmp / "prediction.csv", _csv(header, pred))
        if payload is not None:
            (tmp / "payload.json").write_text(json.dumps(payload, indent=2), encoding="utf-8")
            written.append(tmp / "payload.json")
        written.append(tmp / "track.png")
        figure(tmp / "track.png", raw, run_, names, payload is not None)
        written.append(tmp / "report.md")
        (tmp / "report.md").write_text(
            report(args, online, model, raw, run_, payload), encoding="utf-8"
        )
        return written

    written = outdir.write_dir(args.out, build)
    errs = run_["late_error_percent"]
    print(
        f"{robot.name}: {len(raw['t'])} rows, {online.counts[3]} change(s) detected "
        f"at t = {', '.join(f'{t:.3g}' for t in run_['changes']) or '-'} s"
    )
    print(
        "one-step-ahead error over the last 20 % (% of RMS torque): "
        + ", ".join(_percent(e) for e in errs)
    )
    if online.counts[1] > 0:
        # The raw rows' error carries the causal q̈'s noise times the inertia: 138 % on a
        # 100 Hz UR5 stand-in's barely excited base joint, whose model missed 18 %.
        print(
            "  running level on the low-passed rows (nearer to what the model misses; report.md): "
            + ", ".join(_percent(e) for e in _level_percent(online, run_))
        )
    if not np.all(np.isfinite(errs)):
        print(f"  -: {NO_TORQUE}")
    common.say_noise_floor(
        robot.joint_names, robot.joint_types, run_["late_noise"], run_["late_error_rms"], errs
    )
    still = measurements.barely_moving(robot, raw["q"])
    if still:
        print(f"warning: {measurements.barely_moving_warning(still)}")
    if online.counts[1] == 0:
        print(
            f"warning: no row updated the estimate: {_nothing_learned(online, raw)}; "
            "model.json is the starting model (--model), unchanged"
        )
    note = _ekf_not_started(online.settings)
    if note:
        print(f"note: {note}")
    if online.settings.get("coulomb_search") is not None:
        print(f"Coulomb speed scale v_s = {_coulomb_line(online.settings, scores=False)}")
    choice = online.settings.get("cutoff_choice")
    lowered = online.settings["prediction_cutoff_hz"]
    if choice is not None and lowered < choice["highest_hz"]:
        what = (
            "causal low-pass"
            if online.settings["cutoff_hz"] < choice["highest_hz"]
            else "one-step-ahead predictions' tracker (the ekf's low-pass stays)"
        )
        print(
            f"{what} lowered to {lowered:.3g} Hz (from {choice['highest_hz']:g} Hz) by the "
            f"{choice['noise_of']}' sensor noise (up to {max(choice['sample_noise']):.2g} "
            f"{_noise_unit(choice)}): see report.md"
        )
    if payload is not None:
        print(f"payload: {_payload_line(payload)}")
    print(f"results in {args.out}/ ({len(written)} files: model.json, report.md, figures)")
    return common.EXIT_OK


def track(
    online: prrrp.OnlineIdentifier,
    raw: dict[str, np.ndarray],
    progress: common.Progress | None = None,
) -> dict[str, Any]:
    """Feeds every row of ``raw`` (``t``, ``q``, ``tau``, optional ``qd``) to ``online``;
    returns the one-step-ahead ``prediction`` (S, N), ``estimates`` (rows of t, θ, σ;
    at most :data:`MAX_ESTIMATE_ROWS`), the times of detected ``changes`` and the
    one-step-ahead error per joint over the last 20 % of the rows (% of RMS torque)."""
    t, q, tau = raw["t"], raw["q"], raw["tau"]
    qd = raw.get("qd")
    rows = len(t)
    step = max(1, math.ceil(rows / MAX_ESTIMATE_ROWS))
    p = len(online.parameter_names)
    prediction = np.empty_like(tau, dtype=float)
    estimates = []
    changes = []
    for k in range(rows):
        out = online.update(float(t[k]), q[k], tau[k], None if qd is None else qd[k])
        prediction[k] = out["prediction"]
        if out["change"]:
            changes.append(float(t[k]))
        if k % step == 0 or k == rows - 1:
            sigma = out["sigma"]
            estimates.append(
                np.concatenate(
                    [[t[k]], out["estimate"], np.full(p, np.nan) if sigma is None else sigma]
                )
            )
        if progress is not None and k % 500 == 0:
            progress("track", k, rows)
    if progress is not None:
        progress("track", rows, rows)
        progress.close()
    late = slice(int(0.8 * rows), rows)
    err = prediction[late] - tau[late]
    rms = np.sqrt(np.mean(tau[late] ** 2, axis=0))
    err_rms = np.sqrt(np.mean(err**2, axis=0))
    # A repeated row would read as a noise-free step of the third differences.
    new = np.r_[True, np.diff(t) > 0][late]
    return {
        "prediction": prediction,
        "estimates": np.array(estimates),
        "changes": changes,
        "late_error_percent": 100 * err_rms / np.where(rms > 0, rms, np.nan),
        "late_error_rms": err_rms,
        "late_noise": noise_rms(tau[late][new]),
        "late_rms": rms,
    }


#: What a "-" in place of an error percentage means.
NO_TORQUE = (
    "the joint's torque reads 0 over those rows (a dead or unlogged channel): no percentage "
    "of it to give"
)


def _nothing_learned(online: prrrp.OnlineIdentifier, raw: dict[str, np.ndarray]) -> str:
    """Why no row updated the estimate."""
    span = float(raw["t"][-1] - raw["t"][0])
    return (
        f"the log ({span:.3g} s) ended before the causal filtering "
        f"({online.settings['cutoff_hz']:.3g} Hz) settled, or no joint's torque was measured"
    )


def _level_percent(online: prrrp.OnlineIdentifier, run_: dict[str, Any]) -> list[float]:
    """The running level of the one-step-ahead errors on the low-passed rows, % of each
    joint's RMS torque over the last 20 % of the rows (NaN where that torque is 0)."""
    return [
        100 * s / r if r > 0 else math.nan
        for s, r in zip(online.noise_rms, run_["late_rms"], strict=True)
    ]


def _percent(e: float) -> str:
    """An error percentage, or "-" where the joint had no torque to compare with."""
    return f"{e:.3g}" if np.isfinite(e) else "-"


def _csv(header: list[str], rows: np.ndarray) -> str:
    lines = [",".join(header)]
    lines += [",".join("" if not np.isfinite(v) else repr(float(v)) for v in r) for r in rows]
    return "\n".join(lines) + "\n"


def figure(
    path: Path, raw: dict[str, np.ndarray], run_: dict[str, Any], names: list[str], payload: bool
) -> None:
    """Parameters over time (payload: the mass in kg; else the best determined parameters,
    :func:`shown_parameters`, each over its final magnitude) above the one-step-ahead
    torque error of each joint (N·m or N, a 0.1 s running RMS); detected changes as
    vertical lines."""
    from prrrp import drawing

    est = run_["estimates"]
    t = raw["t"]
    fig, axes = drawing.figure(2, 1, panel=(8.0, 2.7), left=0.9, right=1.2, hspace=0.7, sharex=True)
    a, b = axes[0][0], axes[1][0]
    p = len(names)
    if payload:
        drawing.lines(a, est[:, 0], est[:, 1], label="m")
        # The σ band needs no more points than the panel has pixel columns.
        step = max(1, len(est) // (2 * drawing.pixels(a)[0]))
        e = est[::step]
        a.fill_between(e[:, 0], e[:, 1] - e[:, 1 + p], e[:, 1] + e[:, 1 + p], alpha=0.3, lw=0)
        a.set_ylabel("payload mass (kg)", fontsize=8)
    else:
        shown = shown_parameters(est, p)
        final = np.abs(est[-1, 1 : 1 + p])
        ys = est[:, [1 + k for k in shown]] / final[shown]
        for k, y in zip(shown, ys.T, strict=True):
            drawing.lines(a, est[:, 0], y, lw=0.8, label=names[k])
        # The range of most of each line: a start transient would flatten the rest.
        lo, hi = np.nanpercentile(ys, [2, 98]) if ys.size else (1.0, 1.0)
        pad = max(0.05, 0.1 * (hi - lo))
        a.set_ylim(max(-3.0, lo - pad), min(3.0, hi + pad))
        a.set_ylabel(
            f"parameter / |final value| (1),\nthe {len(shown)} best determined of {p}", fontsize=8
        )
        if len(shown):
            a.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    err = run_["prediction"] - raw["tau"]
    positive = False
    for j in range(err.shape[1]):
        rms = windowed_rms(t, err[:, j], 0.1)
        positive |= bool(np.any(np.isfinite(rms) & (rms > 0)))
        drawing.lines(b, t, rms, lw=0.8, label=f"joint {j + 1}")
    # Errors that are all zero (torque channels that read 0 and a model that predicts 0)
    # have no log scale; matplotlib would warn on stderr.
    if positive:
        b.set_yscale("log")
    b.set_ylabel("one-step-ahead torque\nerror, 0.1 s RMS (N·m, N)", fontsize=8)
    b.set_xlabel("time (s)", fontsize=8)
    b.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    for ax in (a, b):
        for c in run_["changes"]:
            ax.axvline(c, color="k", lw=0.6, ls="--")
    drawing.save(fig, path)


def windowed_rms(t: np.ndarray, x: np.ndarray, width: float) -> np.ndarray:
    """At each row, the RMS of ``x`` over the rows whose time stamps lie within ``width``/2
    (s) of its own (``t`` not decreasing). A window counted in rows spans another duration
    on a log with repeated rows, gaps or an irregular clock (a median step of 0 from
    repeated rows made it one row), and one zero-padded at the ends drew its first and last
    rows too low."""
    t = np.asarray(t, dtype=float)
    sq = np.concatenate([[0.0], np.cumsum(np.asarray(x, dtype=float) ** 2)])
    lo = np.searchsorted(t, t - 0.5 * width, side="left")
    hi = np.searchsorted(t, t + 0.5 * width, side="right")
    # Each window holds at least its own row; max(…, 0) absorbs the cumulative sum's
    # round-off.
    return np.sqrt(np.maximum(sq[hi] - sq[lo], 0.0) / (hi - lo))


def shown_parameters(est: np.ndarray, p: int, most: int = 8) -> list[int]:
    """The parameters the whole-arm figure draws: of the ``p`` columns of ``estimates``
    (rows of t, θ, σ), the at most ``most`` with the smallest relative uncertainty at the
    end, σ/|θ| — or, for a method without σ, the smallest spread over the last fifth of
    the rows over |θ| — among those whose final value is not 0. All 64 of a 7-joint arm
    drawn at once hide every one of them, and the poorly determined ones swing over the
    whole panel."""
    final = np.abs(est[-1, 1 : 1 + p])
    sigma = est[-1, 1 + p : 1 + 2 * p]
    if np.all(np.isnan(sigma)):
        late = est[int(0.8 * len(est)) :, 1 : 1 + p]
        sigma = np.std(late, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = sigma / final
    ok = np.flatnonzero(np.isfinite(rel) & (final > 0))
    return [int(k) for k in ok[np.argsort(rel[ok], kind="stable")][:most]]


def _payload_line(p: dict[str, Any]) -> str:
    """The payload in one line: each quantity with its σ, marked where the run does not
    determine it (``identifiable``); for a run that shows no payload, the sentence that
    says so."""
    none = payloads.no_payload(p)
    if none:
        return none
    ident = p.get("identifiable") or {}

    def pm(v: Any, s: Any, ok: Any, unit: str) -> str:
        if v is None:
            return "-"
        if isinstance(v, list):
            vs = s if s is not None else [None] * len(v)
            oks = ok if isinstance(ok, list) else [ok] * len(v)
            cells = (pm(x, y, o, "") for x, y, o in zip(v, vs, oks, strict=True))
            return "[" + ", ".join(cells) + "]" + unit
        text = f"{v:.4g}" + (f" ± {s:.2g}" if s is not None else "")
        return (text if ok in (None, True) else f"not identifiable ({text})") + unit

    return (
        f"mass {pm(p['mass'], p['mass_sigma'], ident.get('mass'), ' kg')}, "
        f"com {pm(p['com'], p['com_sigma'], ident.get('com'), ' m')}, inertia about com "
        f"{pm(p['inertia'], p['inertia_sigma'], ident.get('inertia'), ' kg·m²')}"
    )


def _coulomb_line(settings: dict[str, Any], scores: bool = True) -> str:
    """The Coulomb scale used and, when it was chosen online, how (with each candidate's
    score if ``scores``)."""
    used = f"{settings['coulomb_scale']:g} rad/s"
    search = settings.get("coulomb_search")
    if search is None:
        return used
    if search["chosen"] is None:
        return (
            f"{used} (the robot's own: the log ended before the choice at "
            f"{search['window_s'][1]:g} s after its first row)"
        )
    how = (
        f"{used}, chosen online from the one-step-ahead errors of {search['window_s'][0]:g}"
        f"–{search['window_s'][1]:g} s"
    )
    if not scores:
        return how
    listed = ", ".join(
        f"{v:g}: {'-' if s is None else f'{s:.4g}'}"
        for v, s in zip(search["candidates"], search["scores"], strict=True)
    )
    return f"{how} (score Σ ln mean e², lower is better; {listed})"


def _ekf_not_started(settings: dict[str, Any]) -> str:
    """What a whole-arm ekf run that ended in its warm-up must say: its model is the
    warm-up's (recursive least squares), not the filter's (empty otherwise)."""
    if settings.get("ekf_running") is not False:
        return ""
    return (
        "the ekf was not running at the end of the log: it was in its warm-up (recursive "
        "least squares on the torques, for "
        f"{settings.get('ekf_warmup_s', 0):g} s of updates with a positive definite mass "
        "matrix, from the start and after a detected change or a restart), so model.json is "
        "the warm-up's estimate; give a longer log, or a prior with --model"
    )


def _noise_unit(choice: dict[str, Any]) -> str:
    """Unit of the sample noise the cut-off was chosen from."""
    return "rad or m" if choice["noise_of"] == "positions" else "rad/s or m/s"


def _cutoff_line(settings: dict[str, Any], given: bool) -> str:
    """The regression's cut-off and, when it was chosen from the noise, why (``given``:
    set by --cutoff)."""
    hz = f"{settings['cutoff_hz']:.3g} Hz"
    choice = settings.get("cutoff_choice")
    if given or choice is None:
        return f"{hz} (--cutoff)"
    if choice["chosen_hz"] is None:
        return f"{hz} (the log ended before the choice after 1 s of filtered rows)"
    noise = choice["sample_noise"]
    seen = (
        f"the {choice['noise_of']}' noise {min(noise):.2g}–{max(noise):.2g} "
        f"{_noise_unit(choice)}, the "
        f"accelerations {min(choice['acceleration_rms']):.2g}–"
        f"{max(choice['acceleration_rms']):.2g} rad/s² or m/s² RMS over the first second"
    )
    top = choice["highest_hz"]
    if settings["cutoff_hz"] < top:
        return (
            f"{hz}, lowered from {top:g} Hz ({seen}: at {top:g} Hz the noise in q̈ was above "
            "a tenth of their RMS), the one-step-ahead predictions' tracker with it"
        )
    if settings["prediction_cutoff_hz"] < top:
        return (
            f"{hz} (the whole-arm EKF's filter measures q and q̇, not q̈: not lowered); "
            f"the one-step-ahead predictions' tracker {settings['prediction_cutoff_hz']:.3g}"
            f" Hz ({seen})"
        )
    return f"{hz} ({seen})"


def report(
    args: argparse.Namespace,
    online: prrrp.OnlineIdentifier,
    model: prrrp.IdentifiedModel,
    raw: dict[str, np.ndarray],
    run_: dict[str, Any],
    payload: dict[str, Any] | None,
) -> str:
    rows, updates, repeated, changes = online.counts
    t = raw["t"]
    lines = [
        f"# prrrp track: {model.robot.name}",
        "",
        f"- data: `{args.data}` ({rows} rows over {t[-1] - t[0]:.4g} s; {repeated} repeated "
        f"time stamps; {updates} rows updated the estimate)",
        f"- method: {args.method}{' (payload mode)' if payload is not None else ''}; prior: "
        f"{args.model or 'none'}; forgetting: "
        f"{'none' if args.forgetting is None else f'{args.forgetting:g} s'}; change "
        f"detection: {'off' if args.no_change_detection else 'on'}",
        f"- changes detected: {changes}"
        + (f" (t = {', '.join(f'{c:.4g}' for c in run_['changes'])} s)" if changes else ""),
        f"- Coulomb speed scale v_s: {_coulomb_line(online.settings)}",
        "- causal low-pass of the regression: "
        + _cutoff_line(online.settings, args.cutoff is not None),
    ]
    still = measurements.barely_moving(model.robot, raw["q"])
    if still:
        lines.append(f"- **warning**: {measurements.barely_moving_warning(still)}")
    note = _ekf_not_started(online.settings)
    if note:
        lines.append(f"- **note**: {note}")
    lines += [
        "",
        "## One-step-ahead prediction",
        "",
        "Each row's torque predicted from the estimate before it (`prediction.csv`), over "
        "the last 20 % of the rows. The error of the raw rows includes the torque sensor's "
        "noise and the causal estimate of q̈; the running level of the errors on the "
        f"low-passed rows ({online.settings['cutoff_hz']:.3g} Hz, what the change test and the "
        "estimator's weights use) is nearer to what the model itself misses:",
        "",
        "| joint | RMS torque (N·m or N) | error of the raw rows (%) | running level on the "
        "low-passed rows (N·m or N) | (%) |",
        "|---|---|---|---|---|",
    ]
    for j, (e, s, r, level) in enumerate(
        zip(
            run_["late_error_percent"],
            online.noise_rms,
            run_["late_rms"],
            _level_percent(online, run_),
            strict=True,
        )
    ):
        rel = f"{level:.3g}" if np.isfinite(level) else "-"
        lines.append(
            f"| {model.robot.joint_names[j]} | {r:.3g} | {_percent(e)} | {s:.3g} | {rel} |"
        )
    if not np.all(np.isfinite(run_["late_error_percent"])):
        lines += ["", f"-: {NO_TORQUE}."]
    if payload is not None:
        lines += ["", "## Payload", "", _payload_line(payload) + " (`payload.json`)."]
    lines += [
        "",
        "## Files",
        "",
        "- `model.json`: the estimate at the end of the data (`prrrp predict MODEL DATA`)",
        "- `estimates.csv`: t, each estimated parameter, then its σ "
        f"(every {max(1, math.ceil(rows / MAX_ESTIMATE_ROWS))}. row)",
        "- `prediction.csv`: t, tau1..tauN one step ahead",
        "- `track.png`: the best determined parameters (payload: the mass) and the "
        "one-step-ahead error over time",
        "",
        "![track](track.png)",
        "",
    ]
    return "\n".join(lines)
