//! Tests of `ops/pen_paths.rs`.

use super::*;
use crate::ops::pen::{pen_field, Profile};
use crate::params::{from_values, to_values, ParamValue};
use std::collections::BTreeMap;

fn path(points: &[[f64; 2]], closed: bool) -> PathValue {
    PathValue::new(points.to_vec(), closed)
}

/// Three strokes, one closed, one with a level outside it (custom samples 0.5 … 0.5), one with
/// its own width and height.
fn three(mode: PenMode) -> PenPathsParams {
    let stroke = PenParams {
        width_px: 10.0,
        taper_px: 6.0,
        mode,
        ..PenParams::default()
    };
    let mut own = path(&[[70.0, 20.0], [90.0, 45.0], [75.0, 70.0]], false);
    own.params
        .insert("width_px".into(), ParamValue::Float(16.0));
    own.params
        .insert("height_px".into(), ParamValue::Float(-3.0));
    let mut custom = path(&[[5.0, 60.0], [40.0, 55.0]], false);
    custom
        .params
        .insert("profile".into(), ParamValue::Choice("custom".into()));
    custom.params.insert(
        "samples_px".into(),
        ParamValue::Profile(vec![0.5, 1.5, 0.5]),
    );
    PenPathsParams {
        paths: vec![
            path(&[[10.0, 10.0], [40.0, 30.0], [20.5, 44.25]], false),
            path(
                &[[30.0, 30.0], [60.0, 28.0], [55.0, 60.0], [28.0, 58.0]],
                true,
            ),
            own,
            custom,
        ],
        stroke,
    }
    .with_step_on_closed()
}

impl PenPathsParams {
    /// The closed path (index 1) raises its inside with a step.
    fn with_step_on_closed(mut self) -> Self {
        self.paths[1]
            .params
            .insert("profile".into(), ParamValue::Choice("step".into()));
        self
    }
}

#[test]
fn the_relief_of_several_paths_is_the_sum_of_their_strokes() {
    let (w, h) = (96, 80);
    for mode in [
        PenMode::Integrable,
        PenMode::Analytic,
        PenMode::DistanceTransform,
    ] {
        let p = three(mode);
        p.validate().unwrap();
        let all = pen_paths_field(w, h, &p, None).unwrap();
        // Each stroke on its own over the whole image (the single-stroke pen), added.
        let singles: Vec<PenOutput> = p
            .strokes()
            .unwrap()
            .iter()
            .map(|s| pen_field(w, h, s).unwrap())
            .collect();
        // The path with its own width and height is the stroke with those.
        assert_eq!(singles[2].height, {
            let s = PenParams {
                points: p.paths[2].points.clone(),
                width_px: 16.0,
                height_px: -3.0,
                ..p.stroke.clone()
            };
            pen_field(w, h, &s).unwrap().height
        });
        let mut worst = 0.0f32;
        for i in 0..w * h {
            let sum = |f: &dyn Fn(&PenOutput) -> f32| singles.iter().map(f).sum::<f32>();
            worst = worst
                .max((all.gradients.p[i] - sum(&|o| o.gradients.p[i])).abs())
                .max((all.gradients.q[i] - sum(&|o| o.gradients.q[i])).abs())
                .max((all.height.data()[i] - sum(&|o| o.height.data()[i])).abs());
        }
        assert!(worst < 1e-5, "{mode:?}: {worst}");
        // Far from every stroke: the sum of their outside levels (0.5 from the custom one).
        assert!((all.height.at(w - 1, 0) - 0.5).abs() < 1e-6, "{mode:?}");
        assert_eq!(all.gradients.p[w - 1], 0.0);
    }
}

#[test]
fn one_path_is_exactly_the_single_stroke() {
    let stroke = PenParams {
        points: vec![[12.0, 40.0], [50.0, 20.0], [70.0, 44.0]],
        width_px: 12.0,
        ..PenParams::default()
    }
    .with_profile(&Profile::Scratch { depth_px: 2.0 });
    let p = PenPathsParams::single(stroke.clone());
    assert_eq!(
        pen_paths_field(80, 60, &p, None).unwrap(),
        pen_field(80, 60, &stroke).unwrap()
    );
    // No paths: nothing drawn.
    let none = PenPathsParams {
        paths: Vec::new(),
        ..p
    };
    let out = pen_paths_field(20, 10, &none, None).unwrap();
    assert!(out.height.data().iter().all(|v| *v == 0.0));
    assert!(out
        .gradients
        .p
        .iter()
        .chain(&out.gradients.q)
        .all(|v| *v == 0.0));
}

/// What the region engine relies on: the pen on a crop, its points shifted, gives the crop of
/// the whole image's relief — bit for bit, whatever strokes the crop meets.
#[test]
fn a_crop_sees_exactly_the_whole_images_relief() {
    let (w, h) = (96, 80);
    for mode in [
        PenMode::Integrable,
        PenMode::Analytic,
        PenMode::DistanceTransform,
    ] {
        let p = three(mode);
        let whole = pen_paths_field(w, h, &p, None).unwrap();
        // The distance transform reads up to half the width and the taper beyond a crop's
        // edge (its halo); the others are exact to the edge.
        let halo: usize = if mode == PenMode::DistanceTransform {
            16
        } else {
            0
        };
        for (x0, y0, cw, ch) in [
            (0usize, 0usize, 96usize, 80usize),
            (33, 17, 30, 25),
            (70, 60, 26, 20),
            (0, 50, 20, 30),
        ] {
            let (gx0, gy0) = (x0.saturating_sub(halo), y0.saturating_sub(halo));
            let (gx1, gy1) = ((x0 + cw + halo).min(w), (y0 + ch + halo).min(h));
            let local = crate::params::shifted(&p, gx0 as f64, gy0 as f64);
            let crop = pen_paths_field(gx1 - gx0, gy1 - gy0, &local, None).unwrap();
            for r in y0..y0 + ch {
                for x in x0..x0 + cw {
                    let (i, j) = (r * w + x, (r - gy0) * (gx1 - gx0) + (x - gx0));
                    assert_eq!(
                        (
                            whole.gradients.p[i],
                            whole.gradients.q[i],
                            whole.height.data()[i]
                        ),
                        (
                            crop.gradients.p[j],
                            crop.gradients.q[j],
                            crop.height.data()[j]
                        ),
                        "{mode:?} crop at ({x0}, {y0}): pixel ({x}, {r})"
                    );
                }
            }
        }
    }
}

#[test]
fn paths_set_only_their_cross_section_and_errors_name_the_path() {
    let mut p = three(PenMode::Integrable);
    p.paths[2]
        .params
        .insert("mode".into(), ParamValue::Choice("analytic".into()));
    let e = p.validate().unwrap_err().to_string();
    assert!(e.contains("path 3 of 4") && e.contains("\"mode\""), "{e}");
    // An open path with a level change, among closed ones: refused, naming it.
    let mut p = three(PenMode::Integrable);
    p.paths[0]
        .params
        .insert("profile".into(), ParamValue::Choice("step".into()));
    let e = p.validate().unwrap_err().to_string();
    assert!(
        e.contains("path 1 of 4") && e.contains("h(-1) = h(1)"),
        "{e}"
    );
    // A misspelt own parameter: the nearest allowed name.
    let mut p = three(PenMode::Integrable);
    p.paths[3]
        .params
        .insert("widht_px".into(), ParamValue::Float(3.0));
    let e = p.validate().unwrap_err().to_string();
    assert!(e.contains("did you mean \"width_px\""), "{e}");
    // Out of the node's range for that parameter.
    let mut p = three(PenMode::Integrable);
    p.paths[3]
        .params
        .insert("width_px".into(), ParamValue::Float(-1.0));
    assert!(p.validate().is_err());
}

#[test]
fn the_file_form_round_trips_and_scales_with_the_level() {
    let p = three(PenMode::Integrable);
    let values = to_values(&p);
    // No `points` nor `closed` of the shared stroke: the paths hold them.
    assert!(values.contains_key("paths") && !values.contains_key("points"));
    assert!(!values.contains_key("closed"));
    assert_eq!(from_values::<PenPathsParams>(&values).unwrap(), p);
    // Text form (`--set`), as parsed and printed.
    let ParamValue::Paths(paths) = &values["paths"] else {
        panic!("{values:?}")
    };
    let text = crate::params::paths_text(paths);
    assert_eq!(&crate::params::parse_paths(&text).unwrap(), paths, "{text}");
    // Two levels coarser: points through the pixel-grid map, own widths divided too.
    let s = crate::params::scaled(&p, 4.0);
    assert_eq!(s.stroke.width_px, 2.5);
    assert_eq!(s.paths[2].params["width_px"], ParamValue::Float(4.0));
    assert_eq!(
        s.paths[2].params["height_px"],
        ParamValue::Float(-3.0 / 4.0)
    );
    assert_eq!(
        s.paths[0].points[1],
        [(40.0 - 1.5) / 4.0, (30.0 - 1.5) / 4.0]
    );
    let _: BTreeMap<String, ParamValue> = to_values(&s);
}
