//! Height + colour → triangle mesh (PLY binary/ASCII, OBJ) with vertex colours and normals.
//!
//! One vertex per pixel inside the mask (coverage ≥ 0.5, or every pixel without a mask) at
//! `(x · pixel_size, −row · pixel_size, z · z_scale)`: `x` right, `y` up, `z` towards the viewer,
//! the frame of the normals, so a mesh viewer shows the surface as the image does. Each 2 × 2
//! block of pixels whose four corners are all inside gives two triangles, counter-clockwise seen
//! from `+z` (front faces towards the viewer). Vertex normals are the image's normals corrected
//! for the scales: slope `(p, q)` becomes `(z_scale/pixel_size)·(p, q)`, so
//! `n ∝ (s·n_x, s·n_y, n_z)` with `s = z_scale / pixel_size`. Colours are the linear albedo
//! encoded as sRGB 8-bit (`uchar red/green/blue` in PLY; `v x y z r g b` in [0, 1] in OBJ, the
//! common MeshLab extension).
//!
//! With a [pinhole camera](MeshParams::camera) the height is the `−Z` of a depth `Z` (the
//! pinhole output of [`crate::raster::integrate::integrate_normals`]) and each vertex is the
//! camera-frame point `z_scale · ((x − cx)·Z/fx, −(row − cy)·Z/fy, −Z)` (`x` right, `y` up,
//! the camera at the origin looking along `−z`: the frame of the normals, so the image's
//! normals are the vertex normals as they are); `pixel_size` is not used and `z_scale`
//! (> 0) is a uniform scale.
//!
//! Files are written atomically (temporary file + rename, see [`io::write_atomic`]).
//!
//! # References
//!
//! - G. Turk, "The PLY polygon file format" (Stanford, 1994).
//! - Wavefront Technologies, "Object files (.obj)", Advanced Visualizer manual, appendix B.

use super::gradient::NZ_EPSILON;
use super::integrate::Pinhole;
use super::{io, srgb, Plane, RgbnImage};
use crate::error::RgbnError;
use rayon::prelude::*;
use std::io::Write;
use std::path::Path;

/// Mesh file format.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum MeshFormat {
    /// PLY, binary little-endian (27 bytes per vertex, 13 per triangle).
    #[default]
    PlyBinary,
    /// PLY, ASCII.
    PlyAscii,
    /// Wavefront OBJ with `v x y z r g b`, `vn` and `f a//a b//b c//c`.
    Obj,
}

/// Parameters of [`build_mesh`] / [`save_mesh`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeshParams {
    pub format: MeshFormat,
    /// Multiplies the height (relief exaggeration), finite and ≠ 0.
    pub z_scale: f32,
    /// World size of one pixel (x and y spacing), finite and > 0.
    pub pixel_size: f32,
    /// A pinhole camera: vertices are unprojected from the depth `−height` (module docs).
    #[serde(default)]
    pub camera: Option<Pinhole>,
}

impl Default for MeshParams {
    fn default() -> Self {
        Self {
            format: MeshFormat::PlyBinary,
            z_scale: 1.0,
            pixel_size: 1.0,
            camera: None,
        }
    }
}

impl MeshParams {
    /// Checks the ranges documented on the fields.
    pub fn validate(&self) -> Result<(), RgbnError> {
        if !(self.z_scale.is_finite() && self.z_scale != 0.0) {
            return Err(RgbnError::param("z_scale", "must be finite and non-zero"));
        }
        if !(self.pixel_size.is_finite() && self.pixel_size > 0.0) {
            return Err(RgbnError::param("pixel_size", "must be finite and > 0"));
        }
        if let Some(c) = &self.camera {
            c.validate()?;
            if self.z_scale <= 0.0 {
                return Err(RgbnError::param(
                    "z_scale",
                    "must be > 0 with a pinhole camera (a uniform scale of the points)",
                ));
            }
        }
        Ok(())
    }
}

/// An indexed triangle mesh with per-vertex normal and sRGB colour.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GridMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub colors_srgb8: Vec<[u8; 3]>,
    /// Counter-clockwise (seen from +z) vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

/// Builds the grid mesh of a height and an image (colour, normals, mask) of the same size.
///
/// # Errors
/// Invalid parameters, sizes that differ, no pixel inside the mask, more than `u32::MAX`
/// vertices.
pub fn build_mesh(
    height: &Plane,
    img: &RgbnImage,
    params: &MeshParams,
) -> Result<GridMesh, RgbnError> {
    params.validate()?;
    let (w, h) = (img.width(), img.height());
    if (height.width(), height.height()) != (w, h) {
        return Err(RgbnError::SizeMismatch {
            what: "height",
            want_w: w,
            want_h: h,
            got_w: height.width(),
            got_h: height.height(),
            path: "mesh".into(),
        });
    }
    let inside = |i: usize| img.mask().is_none_or(|m| m[i] >= 0.5);
    // Vertex index per pixel (u32::MAX = none), by a prefix sum over rows.
    let row_counts: Vec<usize> = (0..h)
        .into_par_iter()
        .map(|r| (0..w).filter(|&x| inside(r * w + x)).count())
        .collect();
    let total: usize = row_counts.iter().sum();
    if total == 0 {
        return Err(RgbnError::EmptyMask { what: "the mesh" });
    }
    if params.camera.is_some() {
        let behind = (0..w * h)
            .into_par_iter()
            .filter(|&i| inside(i) && (height.data()[i].is_nan() || height.data()[i] >= 0.0))
            .count();
        if behind > 0 {
            return Err(RgbnError::param(
                "height",
                format!(
                    "a pinhole mesh needs the height −Z < 0 of a pinhole integration; \
                     {behind} pixels inside have height ≥ 0 (or NaN)"
                ),
            ));
        }
    }
    if total >= u32::MAX as usize {
        return Err(RgbnError::param(
            "mesh",
            format!("{total} vertices exceed the u32 index range"),
        ));
    }
    let mut row_start = Vec::with_capacity(h);
    let mut acc = 0usize;
    for c in &row_counts {
        row_start.push(acc);
        acc += c;
    }
    let mut index = vec![u32::MAX; w * h];
    index.par_chunks_mut(w).enumerate().for_each(|(r, out)| {
        let mut k = row_start[r] as u32;
        for (x, o) in out.iter_mut().enumerate() {
            if inside(r * w + x) {
                *o = k;
                k += 1;
            }
        }
    });
    let s = params.z_scale / params.pixel_size;
    let mut positions = vec![[0.0f32; 3]; total];
    let mut normals = vec![[0.0f32; 3]; total];
    let mut colors_srgb8 = vec![[0u8; 3]; total];
    let (zd, [nx, ny, nz], col) = (height.data(), img.normal(), img.color());
    // Fill per row (each row owns a contiguous vertex range).
    let mut pos_rows: Vec<&mut [[f32; 3]]> = Vec::with_capacity(h);
    let mut nor_rows: Vec<&mut [[f32; 3]]> = Vec::with_capacity(h);
    let mut col_rows: Vec<&mut [[u8; 3]]> = Vec::with_capacity(h);
    let (mut pr, mut nr, mut cr) = (
        positions.as_mut_slice(),
        normals.as_mut_slice(),
        colors_srgb8.as_mut_slice(),
    );
    for &c in &row_counts {
        let (a, b) = pr.split_at_mut(c);
        pos_rows.push(a);
        pr = b;
        let (a, b) = nr.split_at_mut(c);
        nor_rows.push(a);
        nr = b;
        let (a, b) = cr.split_at_mut(c);
        col_rows.push(a);
        cr = b;
    }
    pos_rows
        .into_par_iter()
        .zip(nor_rows)
        .zip(col_rows)
        .enumerate()
        .for_each(|(r, ((pos, nor), colr))| {
            let mut k = 0;
            for x in 0..w {
                let i = r * w + x;
                if !inside(i) {
                    continue;
                }
                let v = if let Some(cam) = &params.camera {
                    let p = cam.point(x, r, -f64::from(zd[i]));
                    pos[k] = p.map(|c| (c * f64::from(params.z_scale)) as f32);
                    [nx[i], ny[i], nz[i]]
                } else {
                    pos[k] = [
                        x as f32 * params.pixel_size,
                        -(r as f32) * params.pixel_size,
                        zd[i] * params.z_scale,
                    ];
                    [s * nx[i], s * ny[i], nz[i].max(NZ_EPSILON)]
                };
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                nor[k] = if len.is_finite() && len > 0.0 {
                    v.map(|c| c / len)
                } else {
                    [0.0, 0.0, 1.0]
                };
                colr[k] = [0, 1, 2].map(|c| srgb::linear_to_srgb8(col[c][i]));
                k += 1;
            }
        });
    // Triangles: quads (x, r)…(x+1, r+1) with all four corners inside.
    let triangles: Vec<[u32; 3]> = (0..h.saturating_sub(1))
        .into_par_iter()
        .flat_map_iter(|r| {
            let index = &index;
            (0..w.saturating_sub(1)).flat_map(move |x| {
                let a = index[r * w + x]; // top-left
                let b = index[r * w + x + 1]; // top-right
                let c = index[(r + 1) * w + x + 1]; // bottom-right
                let d = index[(r + 1) * w + x]; // bottom-left
                let ok = a != u32::MAX && b != u32::MAX && c != u32::MAX && d != u32::MAX;
                // (a, d, c) and (a, c, b) are counter-clockwise with y up.
                let tris = [[a, d, c], [a, c, b]];
                tris.into_iter().filter(move |_| ok)
            })
        })
        .collect();
    Ok(GridMesh {
        positions,
        normals,
        colors_srgb8,
        triangles,
    })
}

/// Writes a mesh atomically in `format`.
///
/// # Errors
/// [`RgbnError::MissingDir`], [`RgbnError::Write`].
pub fn write_mesh(mesh: &GridMesh, path: &Path, format: MeshFormat) -> Result<(), RgbnError> {
    io::write_atomic(path, |out| {
        match format {
            MeshFormat::PlyBinary | MeshFormat::PlyAscii => write_ply(mesh, out, format),
            MeshFormat::Obj => write_obj(mesh, out),
        }
        .map_err(|e| e.to_string())
    })
}

/// [`build_mesh`] then [`write_mesh`]; refuses to overwrite any of `inputs`.
///
/// # Errors
/// As both, and [`RgbnError::OutputIsInput`].
pub fn save_mesh(
    height: &Plane,
    img: &RgbnImage,
    path: &Path,
    inputs: &[&Path],
    params: &MeshParams,
) -> Result<(usize, usize), RgbnError> {
    io::check_output(path, inputs)?;
    let mesh = build_mesh(height, img, params)?;
    write_mesh(&mesh, path, params.format)?;
    Ok((mesh.positions.len(), mesh.triangles.len()))
}

fn write_ply(mesh: &GridMesh, out: &mut impl Write, format: MeshFormat) -> std::io::Result<()> {
    let kind = if format == MeshFormat::PlyBinary {
        "binary_little_endian"
    } else {
        "ascii"
    };
    write!(
        out,
        "ply\nformat {kind} 1.0\ncomment rgbn grid mesh: x right, y up, z towards the viewer\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )?;
    let verts = mesh
        .positions
        .iter()
        .zip(&mesh.normals)
        .zip(&mesh.colors_srgb8);
    if format == MeshFormat::PlyBinary {
        let mut rec = [0u8; 27];
        for ((p, n), c) in verts {
            for (k, v) in p.iter().chain(n).enumerate() {
                rec[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
            }
            rec[24..27].copy_from_slice(c);
            out.write_all(&rec)?;
        }
        let mut rec = [0u8; 13];
        rec[0] = 3;
        for t in &mesh.triangles {
            for (k, v) in t.iter().enumerate() {
                rec[1 + 4 * k..5 + 4 * k].copy_from_slice(&v.to_le_bytes());
            }
            out.write_all(&rec)?;
        }
    } else {
        for ((p, n), c) in verts {
            writeln!(
                out,
                "{} {} {} {} {} {} {} {} {}",
                p[0], p[1], p[2], n[0], n[1], n[2], c[0], c[1], c[2]
            )?;
        }
        for t in &mesh.triangles {
            writeln!(out, "3 {} {} {}", t[0], t[1], t[2])?;
        }
    }
    Ok(())
}

fn write_obj(mesh: &GridMesh, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "# rgbn grid mesh: x right, y up, z towards the viewer")?;
    for (p, c) in mesh.positions.iter().zip(&mesh.colors_srgb8) {
        writeln!(
            out,
            "v {} {} {} {:.4} {:.4} {:.4}",
            p[0],
            p[1],
            p[2],
            f32::from(c[0]) / 255.0,
            f32::from(c[1]) / 255.0,
            f32::from(c[2]) / 255.0
        )?;
    }
    for n in &mesh.normals {
        writeln!(out, "vn {} {} {}", n[0], n[1], n[2])?;
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|v| v + 1);
        writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::sample::Surface;

    /// Parses a PLY header: format and the vertex/face counts, and the header's byte length.
    fn parse_ply_header(bytes: &[u8]) -> (String, usize, usize, usize) {
        let end = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .expect("end_header")
            + 11;
        let text = std::str::from_utf8(&bytes[..end]).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("ply"));
        let (mut fmt, mut nv, mut nf) = (String::new(), 0, 0);
        for l in lines {
            let t: Vec<&str> = l.split_whitespace().collect();
            match t.as_slice() {
                ["format", f, "1.0"] => fmt = (*f).to_string(),
                ["element", "vertex", n] => nv = n.parse().unwrap(),
                ["element", "face", n] => nf = n.parse().unwrap(),
                _ => {}
            }
        }
        (fmt, nv, nf, end)
    }

    #[test]
    fn a_pinhole_mesh_puts_the_vertices_on_the_seen_plane() {
        // A tilted plane n·P = d seen by a pinhole camera (camera at the origin looking along
        // −z): the depth along each pixel's ray is Z = d / (n·ray) with ray = ((x − cx)/fx,
        // −(row − cy)/fy, −1); the height −Z back-projects onto the plane, scaled by z_scale.
        let (w, h) = (20, 16);
        let cam = Pinhole {
            fx: 40.0,
            fy: 36.0,
            cx: 9.0,
            cy: 7.5,
        };
        let nrm = [0.2f64, -0.1, -1.0];
        let d = 5.0f64;
        let ray = |x: usize, r: usize| {
            [
                (x as f64 - cam.cx) / cam.fx,
                -(r as f64 - cam.cy) / cam.fy,
                -1.0,
            ]
        };
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let height = Plane::from_fn(w, h, |x, r| -(d / dot(nrm, ray(x, r))) as f32);
        let n = w * h;
        let img = RgbnImage::new(
            w,
            h,
            [vec![0.5; n], vec![0.5; n], vec![0.5; n]],
            [vec![0.0; n], vec![0.0; n], vec![1.0; n]],
            None,
        )
        .unwrap();
        let z_scale = 2.0f32;
        let zs = f64::from(z_scale);
        let params = MeshParams {
            z_scale,
            camera: Some(cam),
            ..Default::default()
        };
        let mesh = build_mesh(&height, &img, &params).unwrap();
        assert_eq!(mesh.positions.len(), n);
        for (i, p) in mesh.positions.iter().enumerate() {
            let p = [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
            let off = (dot(nrm, p) - zs * d).abs();
            assert!(
                off <= 1e-4 * zs * d,
                "vertex {i}: {p:?} is {off} off the plane"
            );
            // On pixel (x, row)'s ray: p = s·ray with the ray's −1 in z.
            let (x, r) = (i % w, i / w);
            let s = -p[2];
            let want = ray(x, r);
            assert!((p[0] - s * want[0]).abs() <= 1e-4 && (p[1] - s * want[1]).abs() <= 1e-4);
        }
    }

    #[test]
    fn written_meshes_parse_back_with_the_expected_counts() {
        let (img, z) = Surface::Sphere { radius_px: 10.0 }.render(24, 24);
        let mask = img.mask().unwrap();
        let inside = mask.iter().filter(|&&m| m >= 0.5).count();
        // Expected faces: quads with four inside corners.
        let mut quads = 0;
        for r in 0..23 {
            for x in 0..23 {
                let all = [(x, r), (x + 1, r), (x + 1, r + 1), (x, r + 1)]
                    .iter()
                    .all(|&(a, b)| mask[b * 24 + a] >= 0.5);
                quads += usize::from(all);
            }
        }
        assert!(inside > 200 && quads > 150);
        let dir = tempfile::tempdir().unwrap();

        let p = dir.path().join("m.ply");
        let (nv, nf) = save_mesh(&z, &img, &p, &[], &MeshParams::default()).unwrap();
        assert_eq!((nv, nf), (inside, 2 * quads));
        let bytes = std::fs::read(&p).unwrap();
        let (fmt, v, f, hdr) = parse_ply_header(&bytes);
        assert_eq!(fmt, "binary_little_endian");
        assert_eq!((v, f), (inside, 2 * quads));
        assert_eq!(bytes.len(), hdr + 27 * v + 13 * f);
        // First face's indices are in range and its list length is 3.
        let f0 = &bytes[hdr + 27 * v..hdr + 27 * v + 13];
        assert_eq!(f0[0], 3);
        for k in 0..3 {
            let idx = u32::from_le_bytes(f0[1 + 4 * k..5 + 4 * k].try_into().unwrap());
            assert!((idx as usize) < v);
        }
        // Front faces point towards +z: the geometric normal of the first triangle.
        let mesh = build_mesh(&z, &img, &MeshParams::default()).unwrap();
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            let e1 = [b[0] - a[0], b[1] - a[1]];
            let e2 = [c[0] - a[0], c[1] - a[1]];
            assert!(e1[0] * e2[1] - e1[1] * e2[0] > 0.0, "counter-clockwise");
        }
        // Vertex normals are unit and face the viewer.
        assert!(mesh
            .normals
            .iter()
            .all(
                |n| ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-5
                    && n[2] > 0.0
            ));

        let p = dir.path().join("m_ascii.ply");
        let params = MeshParams {
            format: MeshFormat::PlyAscii,
            ..Default::default()
        };
        save_mesh(&z, &img, &p, &[], &params).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let (fmt, v, f, hdr) = parse_ply_header(&bytes);
        assert_eq!((fmt.as_str(), v, f), ("ascii", inside, 2 * quads));
        let body = std::str::from_utf8(&bytes[hdr..]).unwrap();
        assert_eq!(body.lines().count(), v + f);

        let p = dir.path().join("m.obj");
        let params = MeshParams {
            format: MeshFormat::Obj,
            z_scale: 2.0,
            pixel_size: 0.5,
            camera: None,
        };
        save_mesh(&z, &img, &p, &[], &params).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        let count = |pre: &str| text.lines().filter(|l| l.starts_with(pre)).count();
        assert_eq!(
            (count("v "), count("vn "), count("f ")),
            (inside, inside, 2 * quads)
        );
    }

    #[test]
    fn bad_inputs_are_errors() {
        let img = RgbnImage::flat(4, 4, [0.5; 3]);
        let z = Plane::filled(5, 4, 0.0);
        assert!(matches!(
            build_mesh(&z, &img, &MeshParams::default()),
            Err(RgbnError::SizeMismatch { .. })
        ));
        let mut masked = img.clone();
        masked.set_mask(Some(vec![0.0; 16])).unwrap();
        let z = Plane::filled(4, 4, 0.0);
        assert!(matches!(
            build_mesh(&z, &masked, &MeshParams::default()),
            Err(RgbnError::EmptyMask { .. })
        ));
        let bad = MeshParams {
            z_scale: f32::NAN,
            ..Default::default()
        };
        assert!(build_mesh(&z, &img, &bad).is_err());
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nope").join("m.ply");
        assert!(matches!(
            save_mesh(&z, &img, &missing, &[], &MeshParams::default()),
            Err(RgbnError::MissingDir { .. })
        ));
    }
}
