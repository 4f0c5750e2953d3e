use rgbn::eval::region::{Rect, RegionOptions};
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

fn main() {
    let which = std::env::args().nth(1).unwrap_or("stamp".into());
    let node = if which == "stamp" {
        r#"(id: 3, op: "stamp", name: Some("stamp"), pos: (0.0, 0.0), params: { "positions": Points([(1800.0, 1000.0), (2300.0, 1300.0), (1500.0, 800.0)]), "color": Bool(false) }, inputs: { "image": Node(1, "image"), "stamp": Node(2, "image") })"#
    } else {
        r#"(id: 3, op: "pen", name: Some("pen"), pos: (0.0, 0.0), params: { "width_px": Float(20.0), "taper_px": Float(16.0), "height_px": Float(2.0), "points": Points([(1600.0, 1000.0), (1800.0, 1050.0)]) }, inputs: { "image": Node(1, "image") })"#
    };
    let text = format!(
        r#"(
    version: 1,
    next_id: 5,
    outputs: {{ "relit": (node: 4, port: "picture") }},
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int(3840), "height": Int(2160), "shape": Choice("gaussians") }}),
        (id: 2, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int(64), "height": Int(64), "shape": Choice("gaussians") }}),
        {node},
        (id: 4, op: "relight", pos: (0.0, 0.0), inputs: {{ "image": Node(3, "image") }}),
    ],
)"#
    );
    let mut lg = LoadedGraph::from_text(&text, "e.ron", Path::new(".").to_path_buf()).unwrap();
    let ev = Evaluator::default();
    let view = Rect::new(840, 460, 1920, 1080);
    let ropts = RegionOptions {
        tile: std::env::var("TILE")
            .ok()
            .and_then(|t| t.parse().ok())
            .unwrap_or(256),
    };
    let opts = EvalOptions::default();
    let mut pts = vec![[1600.0f64, 1000.0], [1800.0, 1050.0]];
    for it in 0..12 {
        let t0 = Instant::now();
        if which == "stamp" {
            let x = 1800.0 + 7.0 * it as f64;
            lg.set_param(
                "stamp",
                "positions",
                &format!("{x}:1000,2300:1300,1500:800"),
            )
            .unwrap();
        } else {
            let l = pts[pts.len() - 1];
            let a = 0.3 + 0.1 * it as f64;
            pts.push([l[0] + 10.0 * f64::cos(a), l[1] + 10.0 * f64::sin(a)]);
            let s: Vec<String> = pts.iter().map(|p| format!("{}:{}", p[0], p[1])).collect();
            lg.set_param("pen", "points", &s.join(",")).unwrap();
        }
        let t1 = Instant::now();
        let plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).unwrap();
        let t2 = Instant::now();
        let r = ev.eval_region(&plan, "relit", view, &ropts, &opts).unwrap();
        let t3 = Instant::now();
        let _ = ev.eval_region(&plan, "relit", view, &ropts, &opts).unwrap();
        eprintln!(
            "   again (all cached): {:.2} ms",
            t3.elapsed().as_secs_f64() * 1e3
        );
        let t4 = Instant::now();
        let _ = ev
            .eval_region(
                &plan,
                "relit",
                Rect::new(1024, 768, 256, 256),
                &ropts,
                &opts,
            )
            .unwrap();
        eprintln!(
            "   one tile (cached): {:.3} ms",
            t4.elapsed().as_secs_f64() * 1e3
        );
        eprintln!(
            "{it}: set {:.2} plan {:.2} eval {:.2} ms; tiles {:?}",
            (t1 - t0).as_secs_f64() * 1e3,
            (t2 - t1).as_secs_f64() * 1e3,
            (t3 - t2).as_secs_f64() * 1e3,
            r.tiles
                .iter()
                .map(|t| (t.op, t.computed, t.cached, t.reused))
                .collect::<Vec<_>>()
        );
    }
}
