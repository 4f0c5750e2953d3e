#!/usr/bin/env python3
"""Which green convention a glTF model's normal textures have IN IMAGE SPACE, by the model's own
tangent frames.

    python examples/gltf_tangent_frames.py MODEL.gltf|MODEL.glb [...]
    python examples/gltf_tangent_frames.py --self-test

A conforming viewer shades with n = T*r + B*g + N*b, B = cross(N, T.xyz) * T.w, where T is the
primitive's TANGENT attribute when it has one (glTF 2.0, 3.7.2.1). glTF UV (0, 0) is the image's
top-left and v grows downward, so in image space "right" is +dP/du and "up" is -dP/dv. For each
triangle (per corner, from the triangle's UV Jacobian) the supplied frame is

    OpenGL-equivalent   where sign(T . dP/du) * sign(B . (-dP/dv)) > 0  (red+ = right, green+ = up,
                        or both flipped: a 180 degree turn),
    DirectX-equivalent  where it is < 0 (green+ = image down),

weighted by the triangle's area in texels (UV area x width x height; each corner a third). The
fraction of that area whose tangent is turned more than 45 degrees from the image's x axis is
reported too ("turned"): there the red and green channels hold mostly the other image axis'
slope, and an integrability reading in image space no longer measures the convention.

Primitives without TANGENT get MikkTSpace tangents in a conforming viewer, which follow the UVs
and so give the specification's convention (OpenGL in image space) by construction: they are
reported as "no tangents supplied" and not scored.

Frames are taken in mesh space, each primitive once. Node transforms with a negative determinant
(mirrored instances) are reported separately, with the same fractions computed in world space
the way viewers do (N by the inverse transpose, T.xyz by the matrix, B = cross(N, T) * w after).

numpy only (plus the standard library). Reads .gltf (+ .bin, data: URIs) and .glb; accessors
with byteStride, sparse accessors, float and normalized integer components. Not read: Draco /
meshopt compressed primitives (reported), skins and morph targets (the bind pose is used).
"""
import base64
import json
import os
import struct
import sys

import numpy as np

COMPONENT = {5120: ("<i1", 127.0), 5121: ("<u1", 255.0), 5122: ("<i2", 32767.0),
             5123: ("<u2", 65535.0), 5125: ("<u4", None), 5126: ("<f4", None)}
NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


class GltfError(Exception):
    pass


# ----------------------------------------------------------------------------- loading

def load(path):
    """(gltf json, list of buffer bytes or None, base directory)."""
    with open(path, "rb") as f:
        data = f.read()
    base = os.path.dirname(os.path.abspath(path))
    bin_chunk = None
    if data[:4] == b"glTF":
        if len(data) < 20:
            raise GltfError(f"{path}: truncated GLB header")
        _, _, total = struct.unpack_from("<III", data, 0)
        off, js = 12, None
        while off + 8 <= min(total, len(data)):
            clen, ctype = struct.unpack_from("<II", data, off)
            chunk = data[off + 8: off + 8 + clen]
            if ctype == 0x4E4F534A:
                js = json.loads(chunk.decode("utf-8"))
            elif ctype == 0x004E4942:
                bin_chunk = chunk
            off += 8 + clen
        if js is None:
            raise GltfError(f"{path}: GLB without a JSON chunk")
        g = js
    else:
        try:
            g = json.loads(data.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise GltfError(f"{path}: not glTF JSON ({e})")
    bufs = []
    for i, b in enumerate(g.get("buffers", [])):
        uri = b.get("uri")
        if uri is None:
            bufs.append(bin_chunk)
        elif uri.startswith("data:"):
            bufs.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            p = os.path.join(base, unquote(uri))
            try:
                with open(p, "rb") as f:
                    bufs.append(f.read())
            except OSError:
                bufs.append(None)  # reported when an accessor needs it
    return g, bufs, base


def unquote(uri):
    from urllib.parse import unquote as uq
    return uq(uri)


def view_bytes(g, bufs, vi):
    bv = g["bufferViews"][vi]
    buf = bufs[bv["buffer"]]
    if buf is None:
        raise GltfError(f"buffer {bv['buffer']} ({g['buffers'][bv['buffer']].get('uri')}) "
                        "is missing")
    off = bv.get("byteOffset", 0)
    return buf[off: off + bv["byteLength"]], bv.get("byteStride")


def read_accessor(g, bufs, ai):
    """Accessor ai as float64 array (count, ncomp); normalized integers mapped to [0,1]/[-1,1]."""
    a = g["accessors"][ai]
    dt, norm_div = COMPONENT[a["componentType"]]
    nc = NCOMP[a["type"]]
    count = a["count"]
    item = np.dtype(dt).itemsize
    if "bufferView" in a:
        raw, stride = view_bytes(g, bufs, a["bufferView"])
        off = a.get("byteOffset", 0)
        stride = stride or item * nc
        need = off + (count - 1) * stride + item * nc if count else 0
        if need > len(raw):
            raise GltfError(f"accessor {ai} runs past its bufferView")
        arr = np.ndarray((count, nc), dtype=dt, buffer=raw, offset=off,
                         strides=(stride, item)).astype(np.float64)
    else:
        arr = np.zeros((count, nc))
    sp = a.get("sparse")
    if sp:
        idt, _ = COMPONENT[sp["indices"]["componentType"]]
        iraw, _ = view_bytes(g, bufs, sp["indices"]["bufferView"])
        idx = np.frombuffer(iraw, dtype=idt, count=sp["count"],
                            offset=sp["indices"].get("byteOffset", 0)).astype(np.int64)
        vraw, _ = view_bytes(g, bufs, sp["values"]["bufferView"])
        vals = np.frombuffer(vraw, dtype=dt, count=sp["count"] * nc,
                             offset=sp["values"].get("byteOffset", 0)).reshape(-1, nc)
        arr[idx] = vals.astype(np.float64)
    if a.get("normalized") and norm_div:
        arr = np.maximum(arr / norm_div, -1.0)
    return arr


def triangles(g, bufs, prim, nverts):
    mode = prim.get("mode", 4)
    if "indices" in prim:
        idx = read_accessor(g, bufs, prim["indices"])[:, 0].astype(np.int64)
    else:
        idx = np.arange(nverts)
    if mode == 4:
        idx = idx[: len(idx) // 3 * 3]
        return idx.reshape(-1, 3)
    if mode == 5:
        n = len(idx) - 2
        if n <= 0:
            return np.zeros((0, 3), np.int64)
        k = np.arange(n)
        even = k % 2 == 0
        a, b, c = idx[k], idx[k + 1], idx[k + 2]
        return np.stack([a, np.where(even, b, c), np.where(even, c, b)], 1)
    if mode == 6:
        n = len(idx) - 2
        if n <= 0:
            return np.zeros((0, 3), np.int64)
        k = np.arange(n)
        return np.stack([np.full(n, idx[0]), idx[k + 1], idx[k + 2]], 1)
    return None  # points / lines: no faces


# ----------------------------------------------------------------------------- images

def image_size(data):
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return struct.unpack(">II", data[16:24])
    if data[:2] == b"\xff\xd8":
        i = 2
        while i + 4 <= len(data):
            if data[i] != 0xFF:
                i += 1
                continue
            m = data[i + 1]
            if m in (0xD8, 0x01) or 0xD0 <= m <= 0xD7 or m == 0xFF:
                i += 2 if m != 0xFF else 1
                continue
            seg = struct.unpack(">H", data[i + 2: i + 4])[0]
            if m in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE,
                     0xCF):
                h, w = struct.unpack(">HH", data[i + 5: i + 9])
                return w, h
            i += 2 + seg
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return None
    return None


def image_info(g, bufs, base, ii):
    """(name, (w, h) or None)."""
    im = g["images"][ii]
    name = im.get("uri") or im.get("name") or f"image{ii}"
    data = None
    try:
        if "bufferView" in im:
            data, _ = view_bytes(g, bufs, im["bufferView"])
        elif im.get("uri", "").startswith("data:"):
            data = base64.b64decode(im["uri"].split(",", 1)[1])
        elif "uri" in im:
            with open(os.path.join(base, unquote(im["uri"])), "rb") as f:
                data = f.read(1 << 16)
    except (OSError, GltfError):
        data = None
    if not name.startswith("data:"):
        name = unquote(name)
    else:
        name = f"image{ii} (data URI)"
    return name, (image_size(data) if data else None)


def texture_source(tex):
    if "source" in tex:
        return tex["source"]
    for ext in tex.get("extensions", {}).values():
        if isinstance(ext, dict) and "source" in ext:
            return ext["source"]
    return None


def normal_slots(mat):
    """[(slot name, textureInfo)] of a material's tangent-space normal textures."""
    out = []
    if "normalTexture" in mat:
        out.append(("normalTexture", mat["normalTexture"]))
    cc = mat.get("extensions", {}).get("KHR_materials_clearcoat", {})
    if "clearcoatNormalTexture" in cc:
        out.append(("clearcoatNormalTexture", cc["clearcoatNormalTexture"]))
    return out


# ----------------------------------------------------------------------------- frames

def frame_votes(P, N, T4, UV, tri, wh):
    """Per triangle: texel area, and per corner the sign of the frame (+1 OpenGL-equivalent,
    -1 DirectX-equivalent, 0 undefined) and whether its tangent is turned > 45 degrees from the
    image x axis. Returns (area[t], sign[t,3], turned[t,3], uv_degenerate[t])."""
    w, h = wh
    i0, i1, i2 = tri[:, 0], tri[:, 1], tri[:, 2]
    e1, e2 = P[i1] - P[i0], P[i2] - P[i0]
    du1, dv1 = (UV[i1] - UV[i0]).T
    du2, dv2 = (UV[i2] - UV[i0]).T
    det = du1 * dv2 - du2 * dv1
    area = 0.5 * np.abs(det) * w * h
    degenerate = area < 1e-6
    safe = np.where(degenerate, 1.0, det)[:, None]
    dpdu = (dv2[:, None] * e1 - dv1[:, None] * e2) / safe
    dpdv = (du1[:, None] * e2 - du2[:, None] * e1) / safe
    up = -dpdv
    # Gram matrix for expressing a tangent-plane vector in (u, v) coordinates.
    g11 = np.einsum("ij,ij->i", dpdu, dpdu)
    g12 = np.einsum("ij,ij->i", dpdu, dpdv)
    g22 = np.einsum("ij,ij->i", dpdv, dpdv)
    gdet = g11 * g22 - g12 * g12
    gdet_safe = np.where(gdet > 0, gdet, 1.0)
    sign = np.zeros((len(tri), 3))
    turned = np.zeros((len(tri), 3), bool)
    # UV layout mirrored against the surface: (right, up) in image space is left-handed about N.
    nmean = N[i0] + N[i1] + N[i2]
    mirrored = (np.einsum("ij,ij->i", np.cross(dpdu, up), nmean) < 0) & ~degenerate
    for k in range(3):
        ik = tri[:, k]
        t = T4[ik, :3]
        b = np.cross(N[ik], t) * T4[ik, 3:4]
        s = np.sign(np.einsum("ij,ij->i", t, dpdu)) * np.sign(np.einsum("ij,ij->i", b, up))
        sign[:, k] = np.where(degenerate | (gdet <= 0), 0.0, s)
        r1, r2 = np.einsum("ij,ij->i", t, dpdu), np.einsum("ij,ij->i", t, dpdv)
        a = (g22 * r1 - g12 * r2) / gdet_safe
        c = (g11 * r2 - g12 * r1) / gdet_safe
        turned[:, k] = np.abs(a * w) < np.abs(c * h)
    return area, sign, turned, degenerate, mirrored


class Tally:
    def __init__(self):
        self.prims = 0
        self.tris = 0
        self.degenerate = 0
        self.area_tangent = 0.0  # texel area of primitives with TANGENT
        self.area_mikk = 0.0  # texel area of primitives without TANGENT
        self.gl = 0.0
        self.dx = 0.0
        self.undef = 0.0
        self.turned = 0.0
        self.uv_mirrored = 0.0  # texel area whose UV layout is mirrored about N
        self.w_neg = 0.0  # texel area (per corner) with tangent w < 0
        self.mixed_tris = 0  # triangles whose corners disagree
        self.bad_w = 0  # tangent w not +-1 (within 0.01) or zero-length T
        self.slots = set()
        self.texcoords = set()
        self.transforms = []
        self.skipped = []
        self.mirror_inst = 0
        self.inst = 0
        self.world_gl = 0.0
        self.world_dx = 0.0
        self.world_mirror_area = 0.0
        self.world_area = 0.0
        self.mikk_gl = 0.0  # no TANGENT: frames generated from the raw TEXCOORD
        self.mikk_dx = 0.0
        self.mikk_turned = 0.0

    def add(self, area, sign, turned, degenerate, mirrored, w):
        a3 = area[:, None] / 3.0
        self.uv_mirrored += float(area[mirrored].sum())
        self.w_neg += float((a3 * (w < 0)).sum())
        self.gl += float((a3 * (sign > 0)).sum())
        self.dx += float((a3 * (sign < 0)).sum())
        self.undef += float((a3 * (sign == 0)).sum())
        self.turned += float((a3 * turned).sum())
        nd = ~degenerate
        self.mixed_tris += int(((sign[nd] > 0).any(1) & (sign[nd] < 0).any(1)).sum())


def face_tangents(P, N, UV, tri):
    """Per-corner tangents the way MikkTSpace orients them, from one triangle's UV Jacobian
    (T along dP/du made orthogonal to N, w so that B points along -dP/dv, i.e. image up), with
    the triangles' vertices unshared. Returns (P, N, UV, T4) per corner."""
    i0, i1, i2 = tri.T
    e1, e2 = P[i1] - P[i0], P[i2] - P[i0]
    du1, dv1 = (UV[i1] - UV[i0]).T
    du2, dv2 = (UV[i2] - UV[i0]).T
    det = du1 * dv2 - du2 * dv1
    safe = np.where(det == 0, 1.0, det)[:, None]
    dpdu = (dv2[:, None] * e1 - dv1[:, None] * e2) / safe
    dpdv = (du1[:, None] * e2 - du2[:, None] * e1) / safe
    flat = tri.reshape(-1)
    n = N[flat]
    du = np.repeat(dpdu, 3, 0)
    up = -np.repeat(dpdv, 3, 0)
    t = du - n * np.einsum("ij,ij->i", n, du)[:, None]
    w = np.where(np.einsum("ij,ij->i", np.cross(n, t), up) < 0, -1.0, 1.0)
    return P[flat], n, UV[flat], np.concatenate([t, w[:, None]], 1)


def uv_transform(uv, ext):
    off = np.array(ext.get("offset", [0.0, 0.0]), float)
    rot = float(ext.get("rotation", 0.0))
    sc = np.array(ext.get("scale", [1.0, 1.0]), float)
    c, s = np.cos(rot), np.sin(rot)
    rm = np.array([[c, -s], [s, c]])  # GLSL mat3(c, s, 0, -s, c, 0, ...) is column-major
    return (uv * sc) @ rm.T + off


def node_matrices(g):
    """{node index: [global 4x4 matrices]} over the default scene (or all roots)."""
    nodes = g.get("nodes", [])

    def local(n):
        if "matrix" in n:
            return np.array(n["matrix"], float).reshape(4, 4).T
        t = np.eye(4)
        t[:3, 3] = n.get("translation", [0, 0, 0])
        x, y, z, w = n.get("rotation", [0, 0, 0, 1])
        r = np.eye(4)
        r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        s = np.diag(list(n.get("scale", [1, 1, 1])) + [1])
        return t @ r @ s

    out = {}
    scenes = g.get("scenes", [])
    if scenes:
        roots = scenes[g.get("scene", 0)].get("nodes", [])
    else:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    stack = [(r, np.eye(4), 0) for r in roots]
    while stack:
        i, parent, depth = stack.pop()
        if depth > 256:
            raise GltfError("node hierarchy deeper than 256 (cycle?)")
        m = parent @ local(nodes[i])
        out.setdefault(i, []).append(m)
        for c in nodes[i].get("children", []):
            stack.append((c, m, depth + 1))
    return out


def analyse(path):
    g, bufs, base = load(path)
    tallies = {}  # image index -> Tally
    textures = g.get("textures", [])
    mats = g.get("materials", [])
    meshes = g.get("meshes", [])

    def prim_images(prim):
        """[(image index, slot, texCoord, transform ext)] for the primitive's materials."""
        mis = []
        if "material" in prim:
            mis.append(prim["material"])
        for mp in prim.get("extensions", {}).get("KHR_materials_variants", {}).get("mappings",
                                                                                  []):
            mis.append(mp["material"])
        out, seen = [], set()
        for mi in mis:
            for slot, info in normal_slots(mats[mi]):
                src = texture_source(textures[info["index"]])
                if src is None:
                    continue
                tt = info.get("extensions", {}).get("KHR_texture_transform")
                tc = info.get("texCoord", 0)
                if tt and "texCoord" in tt:
                    tc = tt["texCoord"]
                key = (src, slot, tc, json.dumps(tt, sort_keys=True))
                if key not in seen:
                    seen.add(key)
                    out.append((src, slot, tc, tt))
        return out

    sizes = {}

    def size_of(src):
        if src not in sizes:
            sizes[src] = image_info(g, bufs, base, src)
        return sizes[src]

    def prim_arrays(prim):
        at = prim["attributes"]
        P = read_accessor(g, bufs, at["POSITION"])
        N = read_accessor(g, bufs, at["NORMAL"]) if "NORMAL" in at else None
        T4 = read_accessor(g, bufs, at["TANGENT"]) if "TANGENT" in at else None
        tri = triangles(g, bufs, prim, len(P))
        return P, N, T4, tri

    mesh_instances = {}
    for ni, ms in node_matrices(g).items():
        n = g["nodes"][ni]
        if "mesh" in n:
            mesh_instances.setdefault(n["mesh"], []).extend(ms)

    for mi, mesh in enumerate(meshes):
        for pi, prim in enumerate(mesh.get("primitives", [])):
            targets = prim_images(prim)
            if not targets:
                continue
            ext = prim.get("extensions", {})
            comp = [e for e in ("KHR_draco_mesh_compression", "EXT_meshopt_compression")
                    if e in ext]
            for src, slot, tc, tt in targets:
                tl = tallies.setdefault(src, Tally())
                tl.slots.add(slot)
                tl.texcoords.add(tc)
                if tt:
                    tl.transforms.append(tt)
            if comp:
                for src, *_ in targets:
                    tallies[src].skipped.append(f"mesh {mi} prim {pi}: {comp[0]}")
                continue
            P, N, T4, tri = prim_arrays(prim)
            if tri is None:
                continue
            for src, slot, tc, tt in targets:
                tl = tallies[src]
                uvkey = f"TEXCOORD_{tc}"
                if uvkey not in prim["attributes"]:
                    tl.skipped.append(f"mesh {mi} prim {pi}: no {uvkey}")
                    continue
                UV = read_accessor(g, bufs, prim["attributes"][uvkey])[:, :2]
                if tt:
                    UV = uv_transform(UV, tt)
                _, wh = size_of(src)
                wh = wh or (1, 1)
                tl.prims += 1
                tl.tris += len(tri)
                if T4 is None or N is None:
                    # The viewer generates tangents (MikkTSpace) from the UVs: OpenGL in image
                    # space by construction when it uses the sampled UVs. With
                    # KHR_texture_transform, a viewer that generates them from the raw TEXCOORD
                    # (as on load) and transforms only at sampling gets the frame checked here.
                    i0, i1, i2 = tri.T
                    d1, d2 = UV[i1] - UV[i0], UV[i2] - UV[i0]
                    ar = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]) * wh[0] * wh[1]
                    tl.area_mikk += float(ar.sum())
                    tl.degenerate += int((ar < 1e-6).sum())
                    if N is not None:
                        raw = read_accessor(g, bufs, prim["attributes"][uvkey])[:, :2]
                        pe, ne, uve, te = face_tangents(P, N, raw, tri)
                        uvt = uv_transform(uve, tt) if tt else uve
                        tri_e = np.arange(len(pe)).reshape(-1, 3)
                        area, sign, turned, deg, mir = frame_votes(pe, ne, te, uvt, tri_e, wh)
                        a3 = area[:, None] / 3.0
                        tl.uv_mirrored += float(area[mir].sum())
                        tl.mikk_gl += float((a3 * (sign > 0)).sum())
                        tl.mikk_dx += float((a3 * (sign < 0)).sum())
                        tl.mikk_turned += float((a3 * turned).sum())
                    continue
                wv = T4[:, 3]
                tl.bad_w += int(((np.abs(np.abs(wv) - 1) > 0.01)
                                 | (np.linalg.norm(T4[:, :3], axis=1) == 0)).sum())
                area, sign, turned, deg, mir = frame_votes(P, N, T4, UV, tri, wh)
                tl.area_tangent += float(area.sum())
                tl.degenerate += int(deg.sum())
                tl.add(area, sign, turned, deg, mir, wv[tri])
                for m in mesh_instances.get(mi, []):
                    a3 = m[:3, :3]
                    tl.inst += 1
                    Pw = P @ a3.T
                    Nw = N @ np.linalg.inv(a3)  # (inv(A)^T N) as rows
                    Tw = np.concatenate([T4[:, :3] @ a3.T, T4[:, 3:4]], 1)
                    # area stays in texels (same UVs): only the signs change.
                    _, sw, _, _, _ = frame_votes(Pw, Nw, Tw, UV, tri, wh)
                    a_c = area[:, None] / 3.0
                    tl.world_gl += float((a_c * (sw > 0)).sum())
                    tl.world_dx += float((a_c * (sw < 0)).sum())
                    tl.world_area += float(area.sum())
                    if np.linalg.det(a3) < 0:
                        tl.mirror_inst += 1
                        tl.world_mirror_area += float(area.sum())
    return g, tallies, size_of


def pct(a, b):
    return f"{100.0 * a / b:.1f}%" if b > 0 else "-"


def report(path):
    g, tallies, size_of = analyse(path)
    gen = g.get("asset", {}).get("generator")
    print(f"# {path}")
    print(f"  generator: {gen}")
    if not tallies:
        print("  no normal textures")
    for src in sorted(tallies):
        tl = tallies[src]
        name, wh = size_of(src)
        size = f"{wh[0]}x{wh[1]}" if wh else "size unknown (UV area used)"
        print(f"  image {src}: {name} ({size})")
        print(f"    slots: {', '.join(sorted(tl.slots))}; texCoord: "
              f"{', '.join(str(t) for t in sorted(tl.texcoords))}; KHR_texture_transform: "
              + (json.dumps(tl.transforms[0]) + (f" (+{len(tl.transforms) - 1} more)"
                                                  if len(tl.transforms) > 1 else "")
                 if tl.transforms else "no"))
        print(f"    primitives: {tl.prims}, triangles: {tl.tris}, degenerate in UV: "
              f"{tl.degenerate}")
        tot = tl.area_tangent + tl.area_mikk
        if tl.area_tangent == 0 and tl.prims:
            sup = "no tangents supplied (viewer MikkTSpace: OpenGL in image space by construction)"
            mk = tl.mikk_gl + tl.mikk_dx
            if mk > 0:
                sup += (f"\n    frames generated from the raw TEXCOORD"
                        f"{' then KHR_texture_transform' if tl.transforms else ''}: "
                        f"OpenGL-eq {pct(tl.mikk_gl, mk)}, DirectX-eq {pct(tl.mikk_dx, mk)}, "
                        f"turned >45 deg {pct(tl.mikk_turned, tl.area_mikk)}; UV layout "
                        f"mirrored about N: {pct(tl.uv_mirrored, tl.area_mikk)}")
        elif tl.area_mikk == 0:
            sup = "yes"
        else:
            sup = f"partly ({pct(tl.area_tangent, tot)} of texel area)"
        print(f"    tangents supplied: {sup}")
        if tl.area_tangent > 0:
            scored = tl.gl + tl.dx
            print(f"    texel area with supplied tangents: {tl.area_tangent:.0f} "
                  f"(image area {wh[0] * wh[1] if wh else 1})")
            print(f"    OpenGL-equivalent: {pct(tl.gl, scored)}  DirectX-equivalent: "
                  f"{pct(tl.dx, scored)}  (undefined frame: {pct(tl.undef, tl.area_tangent)})")
            print(f"    tangent turned >45 deg from image x: {pct(tl.turned, tl.area_tangent)}; "
                  f"triangles with corners disagreeing: {tl.mixed_tris}; "
                  f"tangents with |w| != 1 or T = 0: {tl.bad_w}")
            print(f"    UV layout mirrored about N: {pct(tl.uv_mirrored, tl.area_tangent)}; "
                  f"tangent w < 0: {pct(tl.w_neg, tl.area_tangent)}")
            if tl.inst:
                ws = tl.world_gl + tl.world_dx
                print(f"    instances: {tl.inst}, mirrored (det < 0): {tl.mirror_inst}; "
                      f"world space over instances: OpenGL-eq {pct(tl.world_gl, ws)}, "
                      f"DirectX-eq {pct(tl.world_dx, ws)}")
        for s in tl.skipped[:5]:
            print(f"    skipped: {s}")
        if len(tl.skipped) > 5:
            print(f"    skipped: ... {len(tl.skipped) - 5} more")
    return tallies


# ----------------------------------------------------------------------------- self-test

def self_test():
    """Two quads side by side in the xy plane (normal +z), the second with mirrored UVs.
    Left quad: u runs along +x, v along -y (image up = +y): T = +x, w = +1 gives B = z x x = +y =
    image up -> OpenGL; w = -1 -> DirectX. Right quad: u runs along -x (mirrored): T = -x with
    w = -1 gives B = -(z x -x) = -(-y) = +y = up -> OpenGL; T = -x, w = +1 -> DirectX.
    T = +x on the mirrored quad (w = +1, B = +y): red+ is image left, green+ is image up -> the
    formula's product is -1 (DirectX)."""
    import tempfile
    P = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0]], np.float32)
    N = np.tile(np.array([0, 0, 1], np.float32), (8, 1))
    # left: u = x, v = 1 - y ; right (mirrored): u = 2 - x, v = 1 - y  (u in [0, 1])
    UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0], [1, 1], [0, 1], [0, 0], [1, 0]], np.float32)
    idx = np.array([0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7], np.uint16)

    def case(tl, tr, wl, wr):
        T = np.array([tl + [wl]] * 4 + [tr + [wr]] * 4, np.float32)
        return T

    def build(T, glb, uv_ubyte=False, stride=False):
        uv = (np.round(UV * 255).astype(np.uint8) if uv_ubyte else UV)
        if uv_ubyte:
            uvb = np.zeros((8, 4), np.uint8)  # 2 bytes of data + 2 padding per element
            uvb[:, :2] = uv
            uv_bytes = uvb.tobytes()
        else:
            uv_bytes = uv.tobytes()
        if stride:  # interleave POSITION and NORMAL in one view, stride 24
            pn = np.concatenate([P, N], 1).astype(np.float32).tobytes()
            parts = [pn, T.tobytes(), uv_bytes, idx.tobytes()]
        else:
            parts = [P.tobytes(), N.tobytes(), T.tobytes(), uv_bytes, idx.tobytes()]
        blob, views = b"", []
        for p in parts:
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(p)})
            blob += p + b"\0" * ((-len(p)) % 4)
        if stride:
            views[0]["byteStride"] = 24
        acc = []
        if stride:
            acc.append({"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3"})
            acc.append({"bufferView": 0, "byteOffset": 12, "componentType": 5126, "count": 8,
                        "type": "VEC3"})
            rest = views[1:]
            base_i = 1
        else:
            acc.append({"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3"})
            acc.append({"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC3"})
            rest = views[2:]
            base_i = 2
        acc.append({"bufferView": base_i, "componentType": 5126, "count": 8, "type": "VEC4"})
        if uv_ubyte:
            views[base_i + 1]["byteStride"] = 4
            acc.append({"bufferView": base_i + 1, "componentType": 5121, "normalized": True,
                        "count": 8, "type": "VEC2"})
        else:
            acc.append({"bufferView": base_i + 1, "componentType": 5126, "count": 8,
                        "type": "VEC2"})
        acc.append({"bufferView": base_i + 2, "componentType": 5123, "count": 12,
                    "type": "SCALAR"})
        del rest
        # a 4x2 PNG header is enough for the size reader
        png = b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + struct.pack(">II", 4, 2)
        g = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
             "nodes": [{"mesh": 0}],
             "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1,
                                                        "TANGENT": 2, "TEXCOORD_0": 3},
                                         "indices": 4, "material": 0}]}],
             "materials": [{"normalTexture": {"index": 0}}],
             "textures": [{"source": 0}],
             "images": [{"uri": "data:image/png;base64," + base64.b64encode(png).decode()}],
             "accessors": acc, "bufferViews": views}
        if glb:
            g["buffers"] = [{"byteLength": len(blob)}]
            js = json.dumps(g).encode()
            js += b" " * ((-len(js)) % 4)
            out = (struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(js) + 8 + len(blob))
                   + struct.pack("<II", len(js), 0x4E4F534A) + js
                   + struct.pack("<II", len(blob), 0x004E4942) + blob)
            return out, ".glb"
        g["buffers"] = [{"byteLength": len(blob),
                         "uri": "data:application/octet-stream;base64,"
                                + base64.b64encode(blob).decode()}]
        return json.dumps(g).encode(), ".gltf"

    def run(T, **kw):
        data, ext = build(T, **kw)
        with tempfile.NamedTemporaryFile(suffix=ext, delete=False) as f:
            f.write(data)
        try:
            _, tallies, _ = analyse(f.name)
        finally:
            os.unlink(f.name)
        tl = tallies[0]
        return tl.gl / (tl.gl + tl.dx), tl

    # area in texels: each quad covers UV area 1 -> 4 x 2 = 8 texels; total 16
    checks = [
        # (left T, right T, w left, w right) -> expected OpenGL-equivalent fraction
        (([1, 0, 0], [-1, 0, 0], 1, -1), 1.0, "standard mirrored halves (T=+x,w=+1 | T=-x,w=-1)"),
        (([1, 0, 0], [-1, 0, 0], -1, 1), 0.0, "both handedness flipped (green down everywhere)"),
        (([1, 0, 0], [1, 0, 0], 1, 1), 0.5, "w=+1 and T=+x on both: the mirrored half is DX"),
        (([-1, 0, 0], [1, 0, 0], 1, -1), 1.0, "180-degree turn on both halves (T=-x,w=+1 | T=+x,w=-1)"),
        (([1, 0, 0], [-1, 0, 0], 1, 1), 0.5, "left OpenGL, mirrored half with wrong w: DX"),
    ]
    ok = True
    for (tl_, tr_, wl, wr), want, label in checks:
        for kw in ({"glb": False}, {"glb": True}, {"glb": True, "uv_ubyte": True, "stride": True}):
            got, t = run(case(tl_, tr_, wl, wr), **kw)
            good = abs(got - want) < 1e-9 and abs(t.area_tangent - 16.0) < 1e-6 \
                and t.tris == 4 and t.degenerate == 0
            ok &= good
            print(f"{'ok  ' if good else 'FAIL'} {label} {kw}: OpenGL-eq {got:.3f} "
                  f"(want {want}), texel area {t.area_tangent:.1f} (want 16), tris {t.tris}")
    # the right quad's UVs are mirrored about N (u runs along -x); its w = -1 in the standard case
    _, t = run(case([1, 0, 0], [-1, 0, 0], 1, -1), glb=False)
    good = abs(t.uv_mirrored - 8.0) < 1e-9 and abs(t.w_neg - 8.0) < 1e-9
    ok &= good
    print(f"{'ok  ' if good else 'FAIL'} UV-mirrored texel area {t.uv_mirrored:.1f} (want 8), "
          f"w < 0 area {t.w_neg:.1f} (want 8)")
    # a tangent along the image's v axis is "turned": T = +y on the left quad
    _, t = run(case([0, 1, 0], [-1, 0, 0], 1, -1), glb=False)
    good = abs(t.turned / t.area_tangent - 0.5) < 1e-9
    ok &= good
    print(f"{'ok  ' if good else 'FAIL'} T along image up on one half: turned "
          f"{t.turned / t.area_tangent:.3f} (want 0.5)")
    # a mirrored node (scale x = -1) flips the world-space handedness of B = cross(N, T) * w
    data, _ = build(case([1, 0, 0], [-1, 0, 0], 1, -1), glb=False)
    g = json.loads(data)
    g["nodes"][0]["scale"] = [-1, 1, 1]
    with tempfile.NamedTemporaryFile("w", suffix=".gltf", delete=False) as f:
        json.dump(g, f)
    try:
        _, tallies, _ = analyse(f.name)
    finally:
        os.unlink(f.name)
    t = tallies[0]
    good = t.mirror_inst == 1 and t.world_gl == 0 and t.gl / (t.gl + t.dx) == 1.0
    ok &= good
    print(f"{'ok  ' if good else 'FAIL'} mirrored node: mesh space OpenGL-eq "
          f"{t.gl / (t.gl + t.dx):.3f} (want 1), world space {t.world_gl / t.world_area:.3f} "
          f"(want 0), mirrored instances {t.mirror_inst}")
    print("self-test:", "passed" if ok else "FAILED")
    return ok


def main(argv):
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__.strip().split("\n\n")[1])
        return 0 if argv else 2
    if argv[0] == "--self-test":
        return 0 if self_test() else 1
    rc = 0
    for p in argv:
        try:
            report(p)
        except (GltfError, OSError, KeyError, IndexError, ValueError) as e:
            print(f"error: {p}: {type(e).__name__}: {e}", file=sys.stderr)
            rc = 1
    return rc


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
