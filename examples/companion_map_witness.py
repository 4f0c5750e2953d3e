#!/usr/bin/env python3
"""A third witness of a normal map's green convention: a co-registered scalar map as geometry.

A glTF material often carries, on the same UVs as its normal map, a scalar map S tied to the
same relief: the occlusion map (R of an ORM: cavities and cracks are dark) or the alpha of a
MASK / BLEND base colour (holes, cut-out edges). Where the relief follows S the same way
whatever the direction of S's edges (a crack or a bevel has one profile, horizontal or
vertical), the slope of the height h lines up with the gradient of S with ONE sign k:

    red   nx ~ -dh/dx                          (x right, both conventions)
    green ny ~ -dh/dy_up  stored OpenGL,   +dh/dy_up  stored DirectX  (image rows grow down)

so  cx = sum nx * dS/dx  and  cy = sum ny * dS/dy_up  have the same sign (that of -k) for
OpenGL and opposite signs for DirectX. Red fixes k; green then tells the convention. Only
isotropy of the h-S relation is assumed, not its sign (AO may darken grooves or the foot of a
step; the alpha edge may be a bevel up or down).

Method: S is resampled to the normal map's size, smoothed (Gaussian, sigma 1 px), and its
central-difference gradient taken; the normals are high-passed (minus a 17 x 17 box mean) so
that broad tilts not tied to S (flat shards, large bends) do not vote. Only the pixels with the
strongest |grad S| count (top 10 %, and above 1/255 per pixel). Reported: correlations
cx, cy (and the cross terms nx-dS/dy_up, ny-dS/dx, which isotropy makes small); per 64 x 64
tile with >= 32 such pixels, a vote: OpenGL if its cx and cy sums have the same sign; the
exact binomial two-sided p of the tile vote. The witness speaks only where |cx| and |cy| are
both >= 0.1 and within a factor 2 of each other (isotropy, as round_features.py asks of its
features), and the tiles agree (majority the same way, p < 0.01); otherwise "uncertain".
On tiny correlations (|c| ~ 0.01) the tile vote alone can be "significant" either way: the
tiles are not independent coin flips there, so p is not enough. It uses neither curl (rgbn's
rule) nor symmetry (round_features.py): a different assumption, so a separate witness. It is
also symmetric: flipping the green channel flips cy and every tile vote exactly.

Usage:
  python examples/companion_map_witness.py NORMAL SCALAR [--channel R|G|B|A|L] [--raw]
  python examples/companion_map_witness.py --gltf MODEL.gltf [MODEL.gltf ...] [--extra] [--raw]
The --gltf form takes every material with a normalTexture and an occlusionTexture (channel R)
and/or a MASK / BLEND baseColorTexture (channel A) on the same texCoord, skipping textures
with KHR_texture_transform; each (normal, scalar, channel) pair is reported once.
--extra adds weaker companions (roughness: G of metallicRoughnessTexture; base colour luma),
which are not geometry but often co-located with it. --raw skips the high-pass.
Needs numpy and Pillow.
"""
import json
import math
import os
import sys
from urllib.parse import unquote

import numpy as np
from PIL import Image

TILE, MIN_PIX, TOP, HP, MIN_CORR = 64, 32, 0.10, 8, 0.1


def box_blur(a, r):
    """Mean over a (2r+1)^2 window, edges replicated."""
    p = np.pad(a, r, mode="edge")
    c = np.pad(p.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    n = 2 * r + 1
    return (c[n:, n:] - c[:-n, n:] - c[n:, :-n] + c[:-n, :-n]) / (n * n)


def gauss(a, sigma=1.0):
    r = int(3 * sigma)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    for ax in (0, 1):
        p = np.pad(a, [(r, r) if i == ax else (0, 0) for i in (0, 1)], mode="edge")
        n = a.shape[ax]
        a = sum(w * (p[i : i + n] if ax == 0 else p[:, i : i + n]) for i, w in enumerate(k))
    return a


def load_scalar(path, channel, size):
    im = Image.open(path)
    if channel == "A" and "A" not in im.getbands():
        if im.mode == "P" and "transparency" in im.info:
            im = im.convert("RGBA")
        else:
            return None  # no alpha: nothing to witness
    band = im.convert("L") if channel == "L" else im.convert("RGBA").getchannel(channel)
    band = band.convert("F")
    if band.size != size:
        band = band.resize(size, Image.BILINEAR)
    return np.asarray(band, dtype=np.float64) / 255.0


def binom_p(k, n):
    """Exact two-sided binomial p for k of n at 1/2."""
    if n == 0:
        return 1.0
    m = min(k, n - k)
    tail = sum(math.comb(n, i) for i in range(m + 1)) / (1 << n)  # exact ints, no overflow
    return min(1.0, 2 * tail)


def witness(normal_path, scalar_path, channel="R", raw=False):
    nim = Image.open(normal_path).convert("RGB")
    s = load_scalar(scalar_path, channel, nim.size)
    if s is None:
        return None
    a = np.asarray(nim, dtype=np.float64) / 127.5 - 1.0
    nx, ny = a[..., 0], a[..., 1]
    if not raw:
        nx, ny = nx - box_blur(nx, HP), ny - box_blur(ny, HP)
    s = gauss(s, 1.0)
    sx = np.zeros_like(s)
    sy = np.zeros_like(s)
    sx[:, 1:-1] = (s[:, 2:] - s[:, :-2]) / 2
    sy[1:-1, :] = -(s[2:] - s[:-2]) / 2  # y up
    g = np.hypot(sx, sy)
    g[[0, -1], :] = 0
    g[:, [0, -1]] = 0
    thr = max(np.quantile(g, 1 - TOP), 1.0 / 255)
    m = g > thr
    res = {"pixels": int(m.sum())}
    if res["pixels"] < MIN_PIX:
        res.update(verdict="none", cx=0.0, cy=0.0, xx=0.0, yx=0.0, gl=0, dx=0, p=1.0)
        return res

    def corr(u, v):
        u, v = u[m], v[m]
        d = math.sqrt(float((u * u).sum() * (v * v).sum()))
        return float((u * v).sum()) / d if d > 0 else 0.0

    res.update(cx=corr(nx, sx), cy=corr(ny, sy), xx=corr(nx, sy), yx=corr(ny, sx))
    px, py = np.where(m, nx * sx, 0.0), np.where(m, ny * sy, 0.0)
    h, w = m.shape
    gl = dx = 0
    for y in range(0, h, TILE):
        for x in range(0, w, TILE):
            t = np.s_[y : y + TILE, x : x + TILE]
            if m[t].sum() < MIN_PIX:
                continue
            v = px[t].sum() * py[t].sum()
            gl += v > 0
            dx += v < 0
    res.update(gl=int(gl), dx=int(dx), p=binom_p(int(gl), int(gl + dx)))
    prod = res["cx"] * res["cy"]
    res["verdict"] = "opengl" if prod > 0 else "directx" if prod < 0 else "none"
    lo, hi = sorted((abs(res["cx"]), abs(res["cy"])))
    tiles = "opengl" if gl > dx else "directx" if dx > gl else "none"
    agree = tiles == res["verdict"] and res["p"] < 0.01
    res["speaks"] = lo >= MIN_CORR and lo >= 0.5 * hi and agree
    return res


def gltf_pairs(path, extra=False):
    d = json.load(open(path))
    base = os.path.dirname(path)
    tex, img = d.get("textures", []), d.get("images", [])

    def uri(info):
        src = tex[info["index"]].get("source")
        u = img[src].get("uri") if src is not None else None
        return os.path.normpath(os.path.join(base, unquote(u))) if u else None

    seen = []
    for mat in d.get("materials", []):
        nt = mat.get("normalTexture")
        if not nt or "extensions" in nt:
            continue
        cands = [(mat.get("occlusionTexture"), "R", "occlusion")]
        bc = mat.get("pbrMetallicRoughness", {}).get("baseColorTexture")
        if mat.get("alphaMode", "OPAQUE") in ("MASK", "BLEND"):
            cands.append((bc, "A", "alpha " + mat["alphaMode"]))
        if extra:  # weaker companions: not geometry, only co-located with it
            mr = mat.get("pbrMetallicRoughness", {}).get("metallicRoughnessTexture")
            cands += [(mr, "G", "roughness"), (bc, "L", "basecolor luma")]
        for t, ch, what in cands:
            if not t or "extensions" in t or t.get("texCoord", 0) != nt.get("texCoord", 0):
                continue
            key = (uri(nt), uri(t), ch)
            if None in key or key in [k for k, _, _ in seen]:
                continue
            seen.append((key, mat.get("name"), what))
    return seen


def line(label, r):
    if r is None:
        return f"{label}: no such channel"
    if r["verdict"] == "none":
        return f"{label}: too few edge pixels ({r['pixels']})"
    v = r["verdict"] if r["speaks"] else f"uncertain ({r['verdict']})"
    return (
        f"{label}: {v} cx {r['cx']:+.3f} cy {r['cy']:+.3f} "
        f"(cross {r['xx']:+.3f} {r['yx']:+.3f}) tiles GL {r['gl']} / DX {r['dx']} p {r['p']:.2g}"
    )


def main():
    try:
        return run(sys.argv[1:])
    except (OSError, ValueError, KeyError, IndexError, TypeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1


def run(args):
    raw, extra = "--raw" in args, "--extra" in args
    args = [a for a in args if a not in ("--raw", "--extra")]
    channel = "R"
    if "--channel" in args:
        i = args.index("--channel")
        if i + 1 >= len(args):
            raise ValueError("--channel needs one of R, G, B, A, L")
        channel = args[i + 1].upper()
        del args[i : i + 2]
    if args[:1] == ["--gltf"] and len(args) > 1:
        for g in args[1:]:
            for (n, s, ch), name, what in gltf_pairs(g, extra):
                label = f"{os.path.basename(n)} | {name} | {what} {os.path.basename(s)}"
                if not (os.path.exists(n) and os.path.exists(s)):
                    print(f"{label}: file absent")
                    continue
                print(line(label, witness(n, s, ch, raw)))
        return 0
    if len(args) != 2 or channel not in ("R", "G", "B", "A", "L"):
        print(__doc__)
        return 2
    print(line(f"{args[0]} vs {args[1]}[{channel}]", witness(args[0], args[1], channel, raw)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
