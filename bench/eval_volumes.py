#!/usr/bin/python3
"""Compare `strata volume DIR --json` output with the synthetic truth (docs/volume.md).

Runs nothing: reads the JSON list written by `strata volume DIR --json > vol.json`
and truth/units.csv of a `strata synth` data set (unit, volume_m3, area_m2,
mean_thickness_m, max_thickness_m). Prints, per unit, the volume error in % and
the mean-thickness error in mm, and whether they meet the volume acceptance
(volume within 1 %, mean thickness within 3 mm).

usage: eval_volumes.py VOLUMES.json TRUTH [--json OUT.json]
  TRUTH: truth/units.csv, or a data folder holding truth/units.csv
"""
import argparse
import csv
import json
import os
import sys

VOLUME_TOLERANCE_PCT = 1.0  # volume within 1 % of the truth
MEAN_TOLERANCE_MM = 3.0     # mean thickness within 3 mm
# without an outline: volume within 0.5 %, the truth inside the
# interval, its half-width under 2 % of the volume, the extent's area within 2 %.
STRICT_VOLUME_PCT = 0.5
STRICT_INTERVAL_PCT = 2.0
STRICT_AREA_PCT = 2.0


def read_truth(path):
    if os.path.isdir(path):
        path = os.path.join(path, "truth", "units.csv")
    with open(path, newline="") as f:
        return {row["unit"]: {k: float(v) for k, v in row.items() if k != "unit"} for row in csv.DictReader(f)}


def evaluate(measured, truth):
    rows = []
    for m in measured:
        unit = str(m["unit"])
        t = truth.get(unit)
        if t is None:
            continue
        vol_err = 100.0 * (m["volume_m3"] - t["volume_m3"]) / t["volume_m3"]
        mean_err = 1000.0 * (m["mean_thickness_m"] - t["mean_thickness_m"])
        area_err = 100.0 * (m["area_m2"] - t["area_m2"]) / t["area_m2"]
        sigma = m.get("volume_sigma_m3")
        interval = m.get("interval_m3")
        inside = interval[0] <= t["volume_m3"] <= interval[1] if interval else None
        half_pct = 100.0 * (interval[1] - m["volume_m3"]) / m["volume_m3"] if interval else None
        rows.append({
            "unit": unit,
            "volume_m3": m["volume_m3"],
            "truth_volume_m3": t["volume_m3"],
            "volume_error_pct": vol_err,
            "volume_sigma_m3": sigma,
            # |error| / sigma: above ~2-3 the stated uncertainty is too small
            "error_in_sigmas": abs(m["volume_m3"] - t["volume_m3"]) / sigma if sigma else None,
            "area_m2": m["area_m2"],
            "truth_area_m2": t["area_m2"],
            "area_error_pct": area_err,
            "mean_thickness_m": m["mean_thickness_m"],
            "truth_mean_thickness_m": t["mean_thickness_m"],
            "mean_thickness_error_mm": mean_err,
            "filled_fraction": m.get("filled_fraction"),
            "interval_m3": interval,
            "confidence": m.get("confidence"),
            "truth_inside_interval": inside,
            "interval_half_width_pct": half_pct,
            "pass": abs(vol_err) <= VOLUME_TOLERANCE_PCT and abs(mean_err) <= MEAN_TOLERANCE_MM,
            "strict_pass": bool(abs(vol_err) <= STRICT_VOLUME_PCT and inside and half_pct is not None
                                and half_pct < STRICT_INTERVAL_PCT and abs(area_err) <= STRICT_AREA_PCT),
        })
    missing = sorted(set(truth) - {r["unit"] for r in rows})
    return rows, missing


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("volumes", help="output of `strata volume DIR --json` (a file)")
    ap.add_argument("truth", help="truth/units.csv or the data folder that holds it")
    ap.add_argument("--json", help="also write the comparison as JSON to this file ('-': stdout only JSON)")
    a = ap.parse_args()
    with open(a.volumes) as f:
        measured = json.load(f)
    rows, missing = evaluate(measured, read_truth(a.truth))
    summary = {
        "units": rows,
        "missing_units": missing,
        "tolerances": {"volume_pct": VOLUME_TOLERANCE_PCT, "mean_thickness_mm": MEAN_TOLERANCE_MM,
                       "strict_volume_pct": STRICT_VOLUME_PCT, "strict_interval_pct": STRICT_INTERVAL_PCT,
                       "strict_area_pct": STRICT_AREA_PCT},
        "all_pass": bool(rows) and not missing and all(r["pass"] for r in rows),
        "all_strict_pass": bool(rows) and not missing and all(r["strict_pass"] for r in rows),
    }
    if a.json == "-":
        print(json.dumps(summary, indent=2))
        return 0 if summary["all_pass"] else 1
    print(f"{'unit':<6} {'volume m3':>10} {'truth m3':>10} {'err %':>8} {'err/sigma':>9} {'+/- %':>6} {'inside':>6} "
          f"{'area m2':>8} {'truth m2':>8} {'area %':>7} {'mean err mm':>11} {'filled %':>8}  ok strict")
    for r in rows:
        es = f"{r['error_in_sigmas']:.1f}" if r["error_in_sigmas"] is not None else "-"
        ff = f"{100 * r['filled_fraction']:.1f}" if r["filled_fraction"] is not None else "-"
        hw = f"{r['interval_half_width_pct']:.2f}" if r["interval_half_width_pct"] is not None else "-"
        ins = "-" if r["truth_inside_interval"] is None else ("yes" if r["truth_inside_interval"] else "NO")
        print(f"{r['unit']:<6} {r['volume_m3']:>10.4f} {r['truth_volume_m3']:>10.4f} {r['volume_error_pct']:>8.2f} "
              f"{es:>9} {hw:>6} {ins:>6} {r['area_m2']:>8.3f} {r['truth_area_m2']:>8.3f} {r['area_error_pct']:>7.2f} "
              f"{r['mean_thickness_error_mm']:>11.2f} {ff:>8}  {'yes' if r['pass'] else 'NO '} "
              f"{'yes' if r['strict_pass'] else 'NO'}")
    for u in missing:
        print(f"{u:<6} no measured volume")
    print(f"acceptance (volume within {VOLUME_TOLERANCE_PCT} %, mean thickness within {MEAN_TOLERANCE_MM} mm): "
          f"{'pass' if summary['all_pass'] else 'FAIL'}")
    print(f"strict (without an outline: volume within {STRICT_VOLUME_PCT} %, truth inside the interval, "
          f"half-width under {STRICT_INTERVAL_PCT} %, area within {STRICT_AREA_PCT} %): "
          f"{'pass' if summary['all_strict_pass'] else 'FAIL'}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(summary, f, indent=2)
    return 0 if summary["all_pass"] else 1


if __name__ == "__main__":
    sys.exit(main())
