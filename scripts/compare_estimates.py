#!/usr/bin/env python3
"""Largest difference between two estimates CSVs (`wheelchair filter --estimates`) in units of
the first file's standard deviations.

Usage: scripts/compare_estimates.py A.csv B.csv [LIMIT]
For every state column (v_m_s ... obstacle_distance_m) and every sd column, prints
max over rows of |a - b| / sd_a (sd_a: the first file's sd of that state) and the time of the
worst row; "overall" is the largest. Rows with sd_a = 0 must be equal (counted otherwise).
Exit 0 when overall <= LIMIT (default 1e-3) and the times agree to 1 us, 1 when not or on bad
input (one line naming the file and line), 2 on usage errors.
Example: scripts/compare_estimates.py before.csv after.csv 1e-3
"""
import sys


def rows(path):
    try:
        with open(path) as f:
            header = f.readline().rstrip("\n")
            for n, line in enumerate(f, start=2):
                try:
                    v = [float(x) for x in line.split(",")]
                except ValueError:
                    sys.exit(f"{path}:{n}: not a row of numbers")
                if len(v) != 17:
                    sys.exit(f"{path}:{n}: {len(v)} columns, expected 17")
                yield header, v
    except OSError as e:
        sys.exit(f"{path}: {e.strerror}")


def main():
    if len(sys.argv) not in (3, 4):
        print(next(l for l in __doc__.splitlines() if l.startswith("Usage")), file=sys.stderr)
        sys.exit(2)
    limit = float(sys.argv[3]) if len(sys.argv) == 4 else 1e-3
    worst, when = [0.0] * 17, [None] * 17
    n, dt_max, zero_sd_diffs, names = 0, 0.0, 0, None
    a_rows, b_rows = rows(sys.argv[1]), rows(sys.argv[2])
    for (ha, a), (hb, b) in zip(a_rows, b_rows):
        if names is None:
            if ha != hb:
                sys.exit(f"{sys.argv[2]}:1: header differs from {sys.argv[1]}'s")
            names = ha.split(",")
        n += 1
        dt_max = max(dt_max, abs(a[0] - b[0]))
        for i in range(1, 17):
            sd = a[9 + (i - 1) % 8]  # state i and its sd column i + 8 share the sd
            d = abs(a[i] - b[i])
            if sd > 0:
                if d / sd > worst[i]:
                    worst[i], when[i] = d / sd, a[0]
            elif d > 0:
                zero_sd_diffs += 1
    if next(a_rows, None) is not None or next(b_rows, None) is not None:
        sys.exit(f"{sys.argv[1]}, {sys.argv[2]}: different numbers of rows")
    if names is None:
        sys.exit(f"{sys.argv[1]}: no rows")
    print(f"rows {n}, max |dt| {dt_max:g} s, differences where sd = 0: {zero_sd_diffs}")
    for i in range(1, 17):
        print(f"  {names[i]:24s} max |diff|/sd {worst[i]:.3g}  (t {when[i]})")
    overall = max(worst)
    print(f"overall max |diff|/sd {overall:.3g} (limit {limit:g})")
    sys.exit(0 if overall <= limit and dt_max <= 1e-6 and zero_sd_diffs == 0 else 1)


if __name__ == "__main__":
    main()
