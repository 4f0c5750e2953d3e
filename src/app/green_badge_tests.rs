//! Tests of `app/green_badge.rs`: the badge of real normal-map files written in each
//! convention (an analytic relief), and the per-frame state machine (one check per key, off
//! the UI thread, again when the file changes).

use super::*;
use crate::graph::Graph;
use crate::params::ParamValue;
use crate::raster::io::{save_normal_map, NormalConvention};
use crate::raster::sample::Surface;

/// Side of the test maps.
const N: usize = 96;

/// Three Gaussian bumps (relief in both directions: the conventions differ), saved as an
/// 8-bit PNG in `convention`.
fn write_bumps(path: &Path, convention: NormalConvention) {
    let (img, _) = Surface::gaussians_for(N).render_sampled(N, N);
    save_normal_map(&img, path, 8, convention).unwrap();
}

fn key(path: &Path, dx: bool) -> BadgeKey {
    let p = LoadParams {
        path: path.display().to_string(),
        dx,
        ..LoadParams::default()
    };
    BadgeKey::of(&p, Path::new("/")).expect("the file exists")
}

#[test]
fn badges_name_the_files_convention_and_the_dx_to_read_it_with() {
    let dir = tempfile::tempdir().unwrap();
    let (gl, dx) = (dir.path().join("gl.png"), dir.path().join("dx.png"));
    write_bumps(&gl, NormalConvention::OpenGl);
    write_bumps(&dx, NormalConvention::DirectX);

    let b = check(&key(&gl, false));
    assert_eq!(b.text, "green: OpenGL", "{b:?}");
    assert!(!b.mismatch);
    assert!(b.hover.contains("OpenGL (+y) most likely"), "{b:?}");
    assert!(!b.hover.contains("load it with"), "{b:?}");

    let b = check(&key(&dx, false));
    assert_eq!(b.text, "green: DirectX — tick dx", "{b:?}");
    assert!(b.mismatch);
    assert!(b.hover.contains("DirectX (-y) most likely"), "{b:?}");
    assert!(b.hover.ends_with("load it with dx ticked"), "{b:?}");

    // Read with dx ticked, the DirectX file's normals are a surface's as held: the badge
    // names the file's convention (as `rgbn info --dx` does) and asks for nothing.
    let b = check(&key(&dx, true));
    assert_eq!(b.text, "green: DirectX", "{b:?}");
    assert!(!b.mismatch);
    assert!(b.hover.contains("DirectX (-y) most likely"), "{b:?}");

    let b = check(&key(&gl, true));
    assert_eq!(b.text, "green: OpenGL — untick dx", "{b:?}");
    assert!(b.mismatch);
    assert!(b.hover.ends_with("load it with dx unticked"), "{b:?}");
}

#[test]
fn flat_and_unreadable_files_say_so_without_failing() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat.png");
    let img = crate::RgbnImage::flat(N, N, [0.5; 3]);
    save_normal_map(&img, &flat, 8, NormalConvention::OpenGl).unwrap();
    let b = check(&key(&flat, false));
    assert_eq!(b.text, "green: uncertain (too little relief)", "{b:?}");
    assert!(b.hover.contains("too little relief"), "{b:?}");

    let bad = dir.path().join("bad.png");
    std::fs::write(&bad, b"not a png at all").unwrap();
    let b = check(&key(&bad, false));
    assert_eq!(b.text, "green: —");
    assert!(b.hover.contains("could not be checked"), "{b:?}");

    // A node naming no file, or a missing one, has no key (and so no badge).
    let none = LoadParams::default();
    assert_eq!(BadgeKey::of(&none, dir.path()), None);
    let missing = LoadParams {
        path: "missing.png".into(),
        ..LoadParams::default()
    };
    assert_eq!(BadgeKey::of(&missing, dir.path()), None);
}

/// Calls `update` (as each frame does) until no check runs; returns the last badges.
fn settle(
    b: &mut GreenBadges,
    g: &Graph,
    base: &Path,
    ctx: &egui::Context,
) -> BTreeMap<NodeId, Badge> {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let out = b.update(g, base, ctx);
        if !b.pending() && out.values().all(|x| *x != Badge::pending()) {
            return out;
        }
        assert!(Instant::now() < deadline, "the checks did not finish");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn each_key_is_checked_once_off_the_ui_thread_and_again_when_the_file_changes() {
    let dir = tempfile::tempdir().unwrap();
    write_bumps(&dir.path().join("dx.png"), NormalConvention::DirectX);
    let mut g = Graph::default();
    let load = g.add_node("load", [0.0, 0.0]);
    let other = g.add_node("normalize", [200.0, 0.0]);
    let set = |g: &mut Graph, name: &str, v: ParamValue| {
        g.nodes
            .get_mut(&load)
            .unwrap()
            .params
            .insert(name.into(), v);
    };
    // A relative path, resolved against the graph's folder.
    set(&mut g, "path", ParamValue::Path("dx.png".into()));
    let ctx = egui::Context::default();
    let mut b = GreenBadges::default();

    // The first frame does not wait: the badge is pending while the thread decodes.
    let first = b.update(&g, dir.path(), &ctx);
    assert_eq!(first.get(&load), Some(&Badge::pending()));
    assert!(!first.contains_key(&other), "only load nodes get a badge");
    let out = settle(&mut b, &g, dir.path(), &ctx);
    assert_eq!(out[&load].text, "green: DirectX — tick dx");
    assert_eq!(b.started, 1);
    // Later frames reuse it.
    for _ in 0..5 {
        assert_eq!(b.update(&g, dir.path(), &ctx)[&load].text, out[&load].text);
    }
    assert_eq!(b.started, 1);

    // Ticking dx is another key: checked once; unticking it again reuses the first check.
    set(&mut g, "dx", ParamValue::Bool(true));
    let out = settle(&mut b, &g, dir.path(), &ctx);
    assert_eq!(out[&load].text, "green: DirectX");
    assert_eq!(b.started, 2);
    set(&mut g, "dx", ParamValue::Bool(false));
    assert_eq!(
        b.update(&g, dir.path(), &ctx)[&load].text,
        "green: DirectX — tick dx"
    );
    assert_eq!(b.started, 2);

    // The file rewritten in the other convention (a new modification time): seen within
    // RESTAT, checked again.
    let path = dir.path().join("dx.png");
    write_bumps(&path, NormalConvention::OpenGl);
    let t = SystemTime::now() + Duration::from_secs(5);
    std::fs::File::options()
        .write(true)
        .open(&path)
        .unwrap()
        .set_modified(t)
        .unwrap();
    std::thread::sleep(RESTAT + Duration::from_millis(50));
    let out = settle(&mut b, &g, dir.path(), &ctx);
    assert_eq!(out[&load].text, "green: OpenGL");
    assert_eq!(b.started, 3);

    // The file gone: no badge (the node shows the load error), no panic.
    std::fs::remove_file(&path).unwrap();
    std::thread::sleep(RESTAT + Duration::from_millis(50));
    assert!(!b.update(&g, dir.path(), &ctx).contains_key(&load));
}
