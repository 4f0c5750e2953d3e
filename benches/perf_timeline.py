#!/usr/bin/env python3
"""Where each thread of a run spends its time, bucket by bucket: the two symbols with the
most samples per thread in every BUCKET seconds (default 0.05), from `perf script`.

  perf record -F 1999 -o p.data target/release/rgbn eval ...
  perf script -i p.data -F tid,time,ip,sym | python3 benches/perf_timeline.py [BUCKET]

A bucket where a thread has 100 samples (at 1999 Hz, 0.05 s) is that thread busy throughout;
a core idle shows as missing samples.
"""
import sys, collections
B = float(sys.argv[1]) if len(sys.argv) > 1 else 0.05
rows = []
for line in sys.stdin:
    p = line.split()
    if len(p) < 3: continue
    try:
        tid = int(p[0]); t = float(p[1].rstrip(':'))
    except ValueError:
        continue
    sym = p[3] if len(p) > 3 else "?"
    rows.append((tid, t, sym))
t0 = min(r[1] for r in rows)
by = collections.defaultdict(collections.Counter)
tids = collections.Counter(r[0] for r in rows)
for tid, t, sym in rows:
    by[(int((t - t0) / B), tid)][sym[:38]] += 1
nb = max(k[0] for k in by) + 1
order = [t for t, _ in tids.most_common()]
for b in range(nb):
    parts = []
    for tid in order:
        c = by.get((b, tid))
        if not c: continue
        n = sum(c.values())
        top = ", ".join(f"{s}:{k}" for s, k in c.most_common(2))
        parts.append(f"[{tid % 1000}] {n:3d} {top}")
    print(f"{b*B:5.2f} | " + " | ".join(parts))
