#!/usr/bin/env python3
"""The table of benches/zarr_format.sh LOG: medians per configuration. Usage: python3 benches/zarr_format_table.py LOG"""
import collections, statistics as st, sys
runs = collections.defaultdict(list); by = {}
for line in open(sys.argv[1]):
    p = line.split()
    if p and p[0] == 'bytes':
        by[p[1]] = (int(p[2]), int(p[4]) if len(p) > 4 else int(p[2]))
    elif len(p) == 5:
        runs[p[0]].append([float(x) for x in p[1:]])
cfgs = ['exr'] + [f'{c}-{k}' for c in ('zstd', 'blosc', 'none') for k in (256, 512, 1024)]
ex = by.get('exr', (1, 1))[0]
print('| format | write wall s | write CPU s | read wall s | read CPU s | read peak RSS MB | bytes (every level) | level 0 bytes | level 0 / EXR ZIP | n |')
print('|---|---|---|---|---|---|---|---|---|---|')
for c in cfgs:
    w, r = runs.get('w-' + c, []), runs.get('r-' + c, [])
    if not w or not r: continue
    m = lambda v, f: st.median(f(x) for x in v)
    b = by.get(c, (0, 0))
    print(f"| {'EXR ZIP (rgbn)' if c == 'exr' else 'zarr ' + c.replace('-', ', chunk ')} | {m(w, lambda x: x[0]):.2f} | {m(w, lambda x: x[1] + x[2]):.2f} | {m(r, lambda x: x[0]):.2f} | {m(r, lambda x: x[1] + x[2]):.2f} | {m(r, lambda x: x[3]) / 1024:.0f} | {b[0]:,} | {b[1]:,} | {b[1] / ex:.3f} | {len(w)} |")
