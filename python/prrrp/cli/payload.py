"""``prrrp payload LOADED --model ARM.json [--mass KG] [--tip LINK] --out DIR``: the payload an
identified arm carries in a run → ``DIR/payload.json``, ``DIR/model.json`` (arm + payload,
for ``prrrp predict``), ``DIR/report.md`` and ``DIR/explained_torque.png``."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import prrrp
from prrrp import drives, outdir
from prrrp import payload as payloads
from prrrp.cli import common
from prrrp.measurements import read_measurements

#: ``prrrp payload --help``.
HELP = "identify the payload an identified arm carries"
DESCRIPTION = (
    "Fits the payload's mass, centre of mass and inertia (about the centre of "
    "mass) at the tip link from the torque that the arm model ARM.json (written by "
    "`prrrp identify --out DIR`) does not explain in LOADED, a run with the payload (CSV or "
    "ROS 2 bag, read and preprocessed as the arm model recorded), with the arm's friction "
    "re-fitted. The result is physically consistent; a quantity the run cannot determine is "
    "reported as not identifiable. Writes DIR/payload.json, DIR/model.json (arm + "
    "payload, for `prrrp predict`), DIR/report.md and DIR/explained_torque.png."
)


def add_parser(sub: Any) -> None:
    p = common.add_command(sub, "payload", run, help=HELP, description=DESCRIPTION)
    p.add_argument("data", metavar="LOADED", help="run with the payload (CSV or ROS 2 bag)")
    p.add_argument("--model", required=True, metavar="ARM.json", help="the arm's identified model")
    p.add_argument(
        "--mass",
        type=common.number,
        metavar="KG",
        help="the payload's known mass (kg): only fit the centre of mass and the inertia "
        "(default: none, the mass is fitted too)",
    )
    p.add_argument(
        "--tip",
        # Not `tip`: that name is the URDF chain option every command checks against --robot.
        dest="payload_tip",
        metavar="LINK",
        help="the chain link that carries the payload (default: the last link)",
    )
    common.add_out_argument(p)
    common.add_topic_argument(p)


def run(args: argparse.Namespace) -> int:
    common.check_factor("--mass", args.mass, unit=" kg")
    outdir.check(args.out)
    try:
        arm = prrrp.IdentifiedModel.load(args.model)
    except prrrp.PrrrpError as e:
        raise common.CliError(f"{args.model}: not an identified model ({e})") from None
    if arm.payload is not None:
        arm = arm.without_payload()
    raw = read_measurements(args.data, arm.robot, topic=args.topic, **drives.recorded(arm))
    data = payloads.to_dataset(arm, raw)
    loaded = arm.identify_payload(data, args.mass, tip=args.payload_tip)
    payload = loaded.payload
    out = Path(args.out)

    def build(tmp: Path) -> list[Path]:
        (tmp / "payload.json").write_text(loaded.payload_json() + "\n", encoding="utf-8")
        loaded.save(tmp / "model.json")
        sources = {"arm model": str(args.model), "loaded run": str(args.data)}
        return [
            tmp / "payload.json",
            tmp / "model.json",
            *payloads.write_report(tmp, arm, loaded, data, sources),
        ]

    written = outdir.write_dir(out, build)
    _summary(payload)
    print(f"results in {out}/ ({len(written)} files: payload.json, model.json, report.md)")
    return common.EXIT_OK


def _fmt(value: Any, sigma: Any, ok: bool, scale: float = 1.0) -> tuple[str, str]:
    if value is None:
        return "-", "-"
    s = "-" if sigma is None else f"{scale * sigma:.2g}"
    return (f"{scale * value:.4g}" if ok else "not identifiable"), s


def _summary(p: dict[str, Any]) -> None:
    ident = p["identifiable"]
    rows = []
    m, ms = _fmt(p["mass"], p.get("mass_sigma"), ident["mass"])
    rows.append(["mass (kg)", m, "given" if p.get("mass_given") else ms])
    com, cs = p.get("com") or [None] * 3, p.get("com_sigma") or [None] * 3
    for k, axis in enumerate("xyz"):
        rows.append([f"COM {axis} (mm)", *_fmt(com[k], cs[k], ident["com"][k], 1000.0)])
    inertia, ins = p.get("inertia") or [None] * 6, p.get("inertia_sigma") or [None] * 6
    for k, name in enumerate(payloads.INERTIA_NAMES):
        rows.append([f"{name} (kg·m²)", *_fmt(inertia[k], ins[k], ident["inertia"][k])])
    print(f"payload at link {p['link']} (centre of mass and inertia in its frame):")
    common.print_table(["quantity", "value", "σ"], rows)
    none = payloads.no_payload(p)
    if none:
        print(f"note: {none}")
    if not all(ident["inertia"]):
        print(
            "note: this run does not determine the payload's inertia to the threshold; a "
            "longer or faster run of the wrist would (the model keeps a physical estimate)"
        )
