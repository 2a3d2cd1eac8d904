"""The tables of a sweep (:mod:`irlsim.workflows.sweep`), made from its route records alone:

- ``sweep.json``: the request, the counts, refusals by reason, every crash and every failure;
- ``sweep.md``: the same as Markdown tables (printed too);
- ``routes.csv``: one row per route (network, route, seed, edges, load, reason, message, driven,
  outcome, failure, end reason).

No wall-clock figure is in them: the same sweep gives the same bytes, resumed or not.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

from irlsim.road.refusals import REASON_NAMES, refusal_reason
from irlsim.utils import atomic_write_text, write_json

#: what the failures table shows of a driven route (collision: what the first collision was,
#: irlsim.sim.collision.collision_line)
FAILURE_COLUMNS = (
    "network",
    "route",
    "seed",
    "failure_reason",
    "failure",
    "end_reason",
    "collision",
    "scenario",
)
CSV_COLUMNS = (
    "network",
    "route",
    "seed",
    "length_m",
    "load",
    "reason",
    "message",
    "driven",
    "outcome",
    "failure_reason",
    "failure",
    "end_reason",
    "collision",
    "edges",
)


def read_records(out: Path, networks: list[str]) -> tuple[list[dict[str, Any]], list[str]]:
    """Every route record of ``networks`` in (network, route) order, and the networks without car lanes."""
    records: list[dict[str, Any]] = []
    no_cars: list[str] = []
    for name in networks:
        folder = out / "records" / name
        marker = folder / "network.json"
        if marker.is_file() and not json.loads(marker.read_text()).get("car_lanes", True):
            no_cars.append(name)
            continue
        for p in sorted(folder.glob("[0-9]*.json")):
            records.append(_classified(json.loads(p.read_text())))
    return records, no_cars


def _classified(rec: dict[str, Any]) -> dict[str, Any]:
    """A record with its reasons sorted now (:mod:`irlsim.road.refusals`), so a record written before the
    list changed is counted by today's list: ``reason`` of a refused load, ``failure_reason`` of a
    driven route (a refusal's reason, 'safety' for a bound broken, 'crash')."""
    if rec["load"] == "refused":
        rec["reason"] = refusal_reason(rec["message"])
    outcome = rec.get("outcome", "")
    reasons = {"refused": refusal_reason(rec.get("failure", "")), "failed": "safety", "crash": "crash"}
    rec["failure_reason"] = reasons.get(outcome, "")
    return rec


def summarize(records: list[dict[str, Any]], networks: list[str], no_cars: list[str]) -> dict[str, Any]:
    """The counts (routes and the networks they are on), refusals by reason, crashes and failures."""

    def count(sel: list[dict[str, Any]]) -> dict[str, int]:
        return {"routes": len(sel), "networks": len({r["network"] for r in sel})}

    loaded = [r for r in records if r["load"] == "loaded"]
    refused = [r for r in records if r["load"] == "refused"]
    driven = [r for r in records if r["driven"]]
    by_outcome = {o: [r for r in driven if r["outcome"] == o] for o in ("ok", "failed", "refused", "crash")}
    reasons = {}
    for reason in REASON_NAMES:
        sel = [r for r in refused if r["reason"] == reason]
        if sel:
            reasons[reason] = {**count(sel), "example": sel[0]["message"]}
    crashes = [
        {
            "network": r["network"],
            "route": r["route"],
            "seed": r["seed"],
            "stage": "load",
            "error": r["message"],
        }
        for r in records
        if r["load"] == "crash"
    ] + [
        {
            "network": r["network"],
            "route": r["route"],
            "seed": r["seed"],
            "stage": "drive",
            "error": r["failure"],
        }
        for r in by_outcome["crash"]
    ]
    failures = [
        {k: "" if r.get(k) is None else r[k] for k in FAILURE_COLUMNS}
        for r in by_outcome["failed"] + by_outcome["refused"]
    ]
    return {
        "counts": {
            "networks": len(networks),
            "networks_without_car_lanes": len(no_cars),
            "drawn": count(records),
            "loaded": count(loaded),
            "refused": count(refused),
            "crashed_loading": count([r for r in records if r["load"] == "crash"]),
            "driven": count(driven),
            "within_bounds": count(by_outcome["ok"]),
            "outside_bounds": count(by_outcome["failed"]),
            "refused_driving": count(by_outcome["refused"]),
            "crashed_driving": count(by_outcome["crash"]),
        },
        "networks_without_car_lanes": no_cars,
        "refused_by_reason": reasons,
        "crashes_by_error": _by_error(crashes),
        "crashes": crashes,
        "failures": failures,
    }


def _by_error(crashes: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Crashes grouped by their line (type, message, where), most routes first: one row per defect."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for c in crashes:
        groups.setdefault((c["stage"], c["error"]), []).append(c)
    rows = [
        {"stage": stage, "error": error, "routes": len(sel), "networks": len({c["network"] for c in sel})}
        for (stage, error), sel in groups.items()
    ]
    return sorted(rows, key=lambda r: (-r["routes"], r["stage"], r["error"]))


#: the rows of the counts table: key of ``counts``, its label
COUNT_ROWS = (
    ("drawn", "routes drawn (a route no pair of edges yields counts as refused, no-path)"),
    ("loaded", "loaded"),
    ("refused", "refused (by reason below)"),
    ("crashed_loading", "crashed while loading"),
    ("driven", "driven by the expert"),
    ("within_bounds", "within the safety bounds"),
    ("outside_bounds", "outside the safety bounds"),
    ("refused_driving", "refused when driven"),
    ("crashed_driving", "crashed while driving"),
)


def markdown(summary: dict[str, Any], request: dict[str, Any]) -> str:
    c = summary["counts"]
    lines = [
        "# Scenario sweep",
        "",
        f"{request['source']}: {c['networks']} networks "
        f"({c['networks_without_car_lanes']} without car lanes), "
        f"{request['routes']} routes each (seed {request['seed']}, at least {request['min_length']:.0f} m), "
        f"the first {request['drive']} that load driven by the expert for at most {request['max_time']:g} s.",
        "",
        "| | routes | networks |",
        "|---|---|---|",
    ]
    lines += [f"| {label} | {c[key]['routes']} | {c[key]['networks']} |" for key, label in COUNT_ROWS]
    lines += [
        "",
        "## Refused, by reason",
        "",
        "| reason | routes | networks | first message |",
        "|---|---|---|---|",
    ]
    for reason, v in summary["refused_by_reason"].items():
        lines.append(f"| {reason} | {v['routes']} | {v['networks']} | {_cell(v['example'])} |")
    lines += ["", "## Crashes (defects of the road or the simulation), by error", ""]
    lines += _rows(summary["crashes_by_error"], ("stage", "error", "routes", "networks"))
    lines += ["", "Every crash:", ""]
    lines += _rows(summary["crashes"], ("network", "route", "seed", "stage", "error"))
    lines += ["", "## Failures (driven outside the safety bounds, or refused when driven)", ""]
    lines += _rows(summary["failures"], FAILURE_COLUMNS)
    if summary["failures"] or summary["crashes"]:
        lines += [
            "",
            "Drive a failure or a crash again (the expert and SUMO's driver, a crash with its traceback): "
            f"`irlsim scenario check SCENARIO --seed SEED --episodes 1 --max-time {request['max_time']:g}`, "
            "SCENARIO the route's file in `scenarios/`.",
        ]
    if summary["networks_without_car_lanes"]:
        lines += ["", "Networks without car lanes: " + ", ".join(summary["networks_without_car_lanes"])]
    return "\n".join(lines) + "\n"


def _cell(text: Any) -> str:
    return str(text).replace("|", "\\|")


def _rows(items: list[dict[str, Any]], cols: tuple[str, ...]) -> list[str]:
    if not items:
        return ["none"]
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    out += ["| " + " | ".join(_cell(it[c]) for c in cols) + " |" for it in items]
    return out


def routes_csv(records: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in records:
        w.writerow({**{k: "" for k in CSV_COLUMNS}, **{k: v for k, v in r.items() if v is not None}})
    return buf.getvalue()


def write_report(out: Path, networks: list[str], request: dict[str, Any]) -> dict[str, Any]:
    """sweep.json, sweep.md and routes.csv into ``out`` (atomically); prints the Markdown and where it
    wrote; returns the summary."""
    records, no_cars = read_records(out, networks)
    summary = {"request": request, **summarize(records, networks, no_cars)}
    md = markdown(summary, request)
    write_json(out / "sweep.json", summary)
    atomic_write_text(out / "sweep.md", md)
    atomic_write_text(out / "routes.csv", routes_csv(records))
    print(md)
    print(f"sweep: {out / 'sweep.md'}, {out / 'sweep.json'}, {out / 'routes.csv'}")
    print(f"  scenario files: {out / 'scenarios'}, per-route records: {out / 'records'}")
    return summary
