//! [`Meta`]: what a parameter's declaration says besides its name and default — its doc line,
//! unit, the range a value must lie in (the hard range, checked on every parse) and the range a
//! slider offers (the soft range, for people).
//!
//! GEGL declares both for each property (`value_range` and `ui_range`, GNOME/gegl:
//! `gegl/property-types/gegl-paramspecs.h`); Graphite has hard and soft ranges. A soft range is
//! what a user slides through: `sigma_normal` accepts any value up to 10⁶, but its slider runs
//! from 0 to 1, and a value beyond the slider can still be typed (up to the hard bounds).

/// Metadata of one parameter: documentation, unit and (for numbers) the accepted range and the
/// slider's range.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Meta {
    /// One-sentence documentation.
    pub doc: &'static str,
    /// Unit shown after the value (e.g. `px`, `rad`, `EV`); empty when unitless.
    pub unit: &'static str,
    /// Inclusive range for numbers (each element for vectors and lists): the hard range, which
    /// every value read from a file, `--set` or the editor must lie in.
    pub range: Option<(f64, f64)>,
    /// The range a slider spans (within [`range`](Self::range)); `None`: the hard range.
    pub soft: Option<(f64, f64)>,
    /// The slider is logarithmic (for scales, σ, tolerances, counts spanning decades).
    pub log: bool,
    /// For paths: true when the file is written (an output), false when it is read.
    pub output: bool,
    /// For paths and texts: an empty value is allowed (meaning "none").
    pub optional: bool,
}

impl Meta {
    /// Metadata with a doc line.
    #[must_use]
    pub const fn new(doc: &'static str) -> Self {
        Self {
            doc,
            unit: "",
            range: None,
            soft: None,
            log: false,
            output: false,
            optional: false,
        }
    }
    /// Sets the unit.
    #[must_use]
    pub const fn unit(mut self, unit: &'static str) -> Self {
        self.unit = unit;
        self
    }
    /// Sets the inclusive (hard) range: values outside are refused.
    #[must_use]
    pub const fn range(mut self, min: f64, max: f64) -> Self {
        self.range = Some((min, max));
        self
    }
    /// Sets the slider's (soft) range, within the hard range: what a user slides through.
    /// Values beyond it, up to the hard range, can still be typed.
    #[must_use]
    pub const fn soft(mut self, min: f64, max: f64) -> Self {
        self.soft = Some((min, max));
        self
    }
    /// Makes the slider logarithmic.
    #[must_use]
    pub const fn log(mut self) -> Self {
        self.log = true;
        self
    }
    /// Marks a path as written rather than read.
    #[must_use]
    pub const fn output(mut self) -> Self {
        self.output = true;
        self
    }
    /// Allows an empty path or text.
    #[must_use]
    pub const fn optional(mut self) -> Self {
        self.optional = true;
        self
    }

    /// The slider of a number with a range: the soft range (the hard range when none is
    /// declared), linear or logarithmic. `None` without a range (an unbounded drag value).
    #[must_use]
    pub fn slider(&self) -> Option<Slider> {
        let (lo, hi) = self.soft.or(self.range)?;
        Some(Slider {
            lo,
            hi,
            log: self.log,
        })
    }

    /// The ranges as `rgbn ops` shows them: ` in [lo, hi]`, then `, slider [a, b]` (and ` log`)
    /// when the slider differs from the hard range; empty without a range.
    #[must_use]
    pub fn ranges_text(&self) -> String {
        let Some((lo, hi)) = self.range else {
            return String::new();
        };
        let mut s = format!(" in [{lo}, {hi}]");
        if let Some(sl) = self.slider().filter(|s| (s.lo, s.hi) != (lo, hi) || s.log) {
            s.push_str(&format!(
                ", slider [{}, {}]{}",
                sl.lo,
                sl.hi,
                if sl.log { " log" } else { "" }
            ));
        }
        s
    }
}

/// The slider of a numeric parameter (from [`Meta::slider`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slider {
    /// Left end.
    pub lo: f64,
    /// Right end.
    pub hi: f64,
    /// Logarithmic.
    pub log: bool,
}

impl Slider {
    /// The smallest positive value of a logarithmic slider starting at 0 (the value 0 sits at
    /// its left end, then the slider runs logarithmically from this value): three decades below
    /// its right end, at least 1 for integers.
    #[must_use]
    pub fn smallest_positive(&self, integer: bool) -> f64 {
        let sp = self.hi * 1e-3;
        if integer {
            sp.max(1.0)
        } else {
            sp
        }
    }

    /// Where `v` sits along the slider, 0 at its left end and 1 at its right end (clamped),
    /// as egui's slider places it: linearly, or by `log10` from `lo` (or from
    /// [`smallest_positive`](Self::smallest_positive) when `lo` is 0). `None` for a
    /// logarithmic slider reaching below 0, which no parameter declares.
    #[must_use]
    pub fn position(&self, v: f64, integer: bool) -> Option<f64> {
        let (lo, hi) = (self.lo, self.hi);
        if hi <= lo {
            return None;
        }
        if v <= lo {
            return Some(0.0);
        }
        if v >= hi {
            return Some(1.0);
        }
        if !self.log {
            return Some((v - lo) / (hi - lo));
        }
        if lo < 0.0 {
            return None;
        }
        let start = if lo == 0.0 {
            self.smallest_positive(integer)
        } else {
            lo
        };
        if v <= start {
            return Some(0.0);
        }
        Some((v.log10() - start.log10()) / (hi.log10() - start.log10()))
    }

    /// Decades a logarithmic slider spans (from [`smallest_positive`](Self::smallest_positive)
    /// when it starts at 0).
    #[must_use]
    pub fn decades(&self, integer: bool) -> f64 {
        let start = if self.lo == 0.0 {
            self.smallest_positive(integer)
        } else {
            self.lo
        };
        (self.hi / start).log10()
    }
}
