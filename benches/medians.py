#!/usr/bin/env python3
"""Medians of the lines "who wall user sys peak-RSS-KB" that benches/whole_process.sh prints.

Usage: python3 benches/medians.py LOG
"""
import collections
import statistics as st
import sys

runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    p = line.split()
    if len(p) == 5:
        runs[p[0]].append([float(x) for x in p[1:]])
for who, v in sorted(runs.items()):
    wall, user, sys_, rss = (st.median(x[k] for x in v) for k in range(4))
    walls = " ".join(f"{x[0]:.2f}" for x in v)
    print(f"{who:12s} n={len(v)} wall {wall:.3f} user {user:.2f} sys {sys_:.2f} "
          f"rss {rss / 1024:.0f} MB  walls {walls}")
