//! Every numeric parameter of every registered operator has a slider a user can slide through:
//! its declared soft range (or its hard range when that is already usable), with the default
//! well inside it. The editor's sliders span exactly these ranges (`editor_menu.rs`).

use rgbn::nodes::registry;
use rgbn::params::{ParamKind, ParamValue};

/// Why a slider is usable.
#[derive(Debug, PartialEq)]
enum Usable {
    /// The default sits between 5 % and 95 % along the slider (linear or logarithmic).
    Inside,
    /// The default is an end of the slider that is also a hard bound: nothing lies beyond it
    /// (opacity 1 of [0, 1], a crop offset 0).
    AtHardBound,
    /// The default is 0 at the left end of a logarithmic slider (an "off" or "automatic" value
    /// the slider starts from).
    LogZero,
}

/// The verdict on one parameter's slider, or why it is not usable.
fn verdict(meta: &rgbn::params::Meta, default: f64, integer: bool) -> Result<Usable, String> {
    let (hard_lo, hard_hi) = meta.range.ok_or("no range: an unbounded drag value")?;
    let s = meta.slider().ok_or("no slider")?;
    // NaN bounds count as empty too.
    if s.lo.partial_cmp(&s.hi) != Some(std::cmp::Ordering::Less) {
        return Err(format!("empty slider [{}, {}]", s.lo, s.hi));
    }
    if s.lo < hard_lo || s.hi > hard_hi {
        return Err(format!(
            "slider [{}, {}] reaches outside the hard range [{hard_lo}, {hard_hi}]",
            s.lo, s.hi
        ));
    }
    if default < s.lo || default > s.hi {
        return Err(format!(
            "default {default} outside the slider [{}, {}]",
            s.lo, s.hi
        ));
    }
    if s.log {
        if s.lo < 0.0 {
            return Err("a logarithmic slider below 0".into());
        }
        // Beyond 7 decades, a pixel of slider is more than a few percent of the value.
        if s.decades(integer) > 7.0 {
            return Err(format!(
                "a logarithmic slider over {:.1} decades",
                s.decades(integer)
            ));
        }
    } else if s.hi - s.lo > 1e4 {
        // Sanity bounds (±10⁴ rad, 0 … 10⁶) as a slider: a pixel of it is worth too much.
        return Err(format!(
            "a linear slider over [{}, {}]: declare a soft range",
            s.lo, s.hi
        ));
    }
    let t = s.position(default, integer).ok_or("no position")?;
    if (0.05..=0.95).contains(&t) {
        return Ok(Usable::Inside);
    }
    if (default == s.lo && s.lo == hard_lo) || (default == s.hi && s.hi == hard_hi) {
        return Ok(Usable::AtHardBound);
    }
    if s.log && s.lo == 0.0 && default == 0.0 {
        return Ok(Usable::LogZero);
    }
    Err(format!(
        "default {default} at {:.1} % of the slider [{}, {}]{}",
        100.0 * t,
        s.lo,
        s.hi,
        if s.log { " (log)" } else { "" }
    ))
}

#[test]
fn every_numeric_parameter_of_every_operator_has_a_usable_slider() {
    let mut bad = Vec::new();
    let mut counts = [0usize; 3];
    for op in registry() {
        for p in op.params() {
            let (default, integer) = match (&p.kind, &p.default) {
                (ParamKind::Float, ParamValue::Float(x)) => (*x, false),
                (ParamKind::Int, ParamValue::Int(i)) => (*i as f64, true),
                _ => continue,
            };
            match verdict(&p.meta, default, integer) {
                Ok(u) => {
                    counts[match u {
                        Usable::Inside => 0,
                        Usable::AtHardBound => 1,
                        Usable::LogZero => 2,
                    }] += 1;
                }
                Err(e) => bad.push(format!("{}.{}: {e}", op.spec().id, p.name)),
            }
        }
    }
    let total: usize = counts.iter().sum::<usize>() + bad.len();
    println!(
        "sliders: {total} numeric parameters; {} with the default inside 5–95 %, {} at a hard bound, {} at a logarithmic slider's zero; {} unusable",
        counts[0],
        counts[1],
        counts[2],
        bad.len()
    );
    assert!(bad.is_empty(), "unusable sliders:\n{}", bad.join("\n"));
    // A registry that lost its numbers would pass vacuously.
    assert!(total > 100, "only {total} numeric parameters");
}

#[test]
fn the_rule_refuses_the_sanity_bounds_sliders_of_before() {
    use rgbn::params::Meta;
    // The bilateral's sigma_normal as it was: 0 … 10⁶ linear, default 0.3.
    let before = Meta::new("").range(0.0, 1e6);
    assert!(verdict(&before, 0.3, false).is_err());
    // The stamp's angle as it was: ±10⁴ rad; the default 0 sits in the middle, but a pixel of
    // the slider is worth a hundred radians.
    let angle = Meta::new("").range(-1e4, 1e4);
    assert!(verdict(&angle, 0.0, false).is_err());
    // With soft ranges: half a turn either way, and 0 … 1 for the σ.
    let angle = angle.soft(-std::f64::consts::PI, std::f64::consts::PI);
    assert_eq!(verdict(&angle, 0.0, false), Ok(Usable::Inside));
    let after = Meta::new("").range(0.0, 1e6).soft(0.0, 1.0);
    assert_eq!(verdict(&after, 0.3, false), Ok(Usable::Inside));
    // Log sliders: the default's position is measured along the log scale.
    let sigma = Meta::new("").range(0.05, 4096.0).soft(0.1, 64.0).log();
    assert_eq!(verdict(&sigma, 2.0, false), Ok(Usable::Inside));
    assert!(
        verdict(&sigma, 0.1, false).is_err(),
        "at the left end, not a hard bound"
    );
    // A default at a hard bound is the slider's end (nothing lies beyond).
    let opacity = Meta::new("").range(0.0, 1.0);
    assert_eq!(verdict(&opacity, 1.0, false), Ok(Usable::AtHardBound));
    // A soft range outside the hard one is refused.
    let outside = Meta::new("").range(0.0, 1.0).soft(-1.0, 1.0);
    assert!(verdict(&outside, 0.5, false).is_err());
}
