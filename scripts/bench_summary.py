#!/usr/bin/env python3
"""Markdown tables from `linebake bench render --json`: GPU ms a frame per data set and
technique, each technique's speed against one (`ll` by default), and per row its passes,
memory and quality. What the README's GPU tables show, from the JSON of one run or of several
of the same size and frames (scripts/bench-gpu runs one a set).

    scripts/bench_summary.py render.json... [--against ll]
"""
import argparse
import json
import sys


def fmt(value, digits=1):
    return f"{value:,.{digits}f}" if isinstance(value, (int, float)) else ""


def rows_of(report):
    """(cache, segments, row) for every row of every run, in the order bench render wrote them."""
    for run in report["runs"]:
        for row in run.get("rows", []):
            yield run.get("cache", "?"), run.get("segments"), row


def key_of(row):
    return row.get("technique", "?"), row.get("transfer_function", "?")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("json", nargs="+", help="the output of linebake bench render --json")
    parser.add_argument("--against", default="ll", help="the technique the others are timed against")
    args = parser.parse_args()
    report = None
    for path in args.json:
        try:
            with open(path, encoding="utf-8") as f:
                part = json.load(f)
            runs = part["runs"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            sys.exit(f"bench_summary: {path}: not the JSON of bench render ({e})")
        if report is None:
            report = dict(part, runs=list(runs))
            continue
        for key in ("size", "frames", "warm_up"):
            if part.get(key) != report.get(key):
                sys.exit(f"bench_summary: {path}: {key} {part.get(key)}, "
                         f"not {report.get(key)} as in {args.json[0]}")
        report["runs"] += runs

    sets, columns, cells = [], [], {}
    for cache, segments, row in rows_of(report):
        label = f"{cache} ({segments:,})" if isinstance(segments, int) else cache
        if label not in sets:
            sets.append(label)
        column = key_of(row)
        if column not in columns:
            columns.append(column)
        cells[label, column] = row
    tfs = {tf for _, tf in columns}
    name = lambda c: c[0] if len(tfs) == 1 else f"{c[0]} ({c[1]})"
    size = report.get("size", ["?", "?"])
    warm_up = report.get("warm_up")
    after = f" after {warm_up} not counted" if warm_up else ""
    print(f"GPU ms a frame, median of {report.get('frames', '?')} frames{after} (max), "
          f"{size[0]}x{size[1]}, {', '.join(sorted(tfs))}:\n")
    print("| set (segments) | " + " | ".join(f"`{name(c)}`" for c in columns) + " |")
    print("|---|" + "---:|" * len(columns))
    for label in sets:
        out = []
        for c in columns:
            row = cells.get((label, c), {})
            if "gpu_ms" in row:
                out.append(f"{fmt(row['gpu_ms']['median'])} ({fmt(row['gpu_ms']['max'])})")
            elif "skipped" in row:
                out.append("skipped")
            elif "failed" in row:
                out.append("failed")
            else:
                out.append("")
        print(f"| {label} | " + " | ".join(out) + " |")

    against = [c for c in columns if c[0] == args.against]
    others = [c for c in columns if c[0] != args.against]
    if against and others:
        print(f"\n`{args.against}`'s GPU ms over each technique's (above 1: faster than `{args.against}`):\n")
        print("| set | " + " | ".join(f"`{name(c)}`" for c in others) + " |")
        print("|---|" + "---:|" * len(others))
        for label in sets:
            out = []
            for c in others:
                base = cells.get((label, (args.against, c[1])), {}).get("gpu_ms", {}).get("median")
                mine = cells.get((label, c), {}).get("gpu_ms", {}).get("median")
                out.append(fmt(base / mine, 2) if base and mine else "")
            print(f"| {label} | " + " | ".join(out) + " |")

    print("\nPer row: passes (median GPU ms), frame memory, frame 0 against the reference; "
          "for tiles, keys and walks over the frames:\n")
    print("| set | technique | passes | frame MiB | PSNR dB / SSIM | tiles: keys, most walks, "
          "first walk / walks again ms | notes |")
    print("|---|---|---|---:|---|---|---|")
    for cache, _, row in rows_of(report):
        passes = ", ".join(f"{p} {fmt(v['median'])}" for p, v in sorted(row.get("passes", {}).items()))
        quality = (f"{fmt(row['psnr_db'])} / {fmt(row['ssim'], 4)}" if "psnr_db" in row else "")
        tiles = row.get("tiles")
        tiles_text = ""
        if tiles:
            frames = tiles.get("frames", [])
            keys = sorted(f.get("keys", 0) for f in frames)
            walks = max((f.get("walks", 0) for f in frames), default=0)
            median_keys = keys[len(keys) // 2] if keys else 0
            tiles_text = (f"{median_keys:,} (median), {walks}, "
                          f"{fmt(tiles.get('first_walk_ms', {}).get('median'))} / "
                          f"{fmt(tiles.get('walks_again_ms', {}).get('median'))}")
        # Late shading's hits that its second test missed (composited in a stand-in colour).
        misses = [f["late_misses"] for f in (tiles or {}).get("frames", []) if "late_misses" in f]
        notes = "; ".join(text for text in (
            f"late misses {sum(misses)}" if misses else None,
            row.get("skipped"), "failed: " + row["failed"] if "failed" in row else None,
            "stopped " + row["stopped"] if "stopped" in row else None,
            row.get("quality_skipped")) if text)
        memory = fmt(row["frame_bytes"] / 2**20) if "frame_bytes" in row else ""
        print(f"| {cache} | `{name(key_of(row))}` | {passes} | {memory} | {quality} | "
              f"{tiles_text} | {notes} |")


if __name__ == "__main__":
    main()
