//! Which compiled twin of a kernel runs: the one place that detects the CPU's vector
//! instructions and reads `RGBN_SIMD`.
//!
//! Hot kernels are compiled several times ("twins"): a portable one (the target's baseline
//! instructions: SSE2 on x86-64, NEON on aarch64, no fused multiply-add), and on x86-64 one for
//! AVX2 + FMA and one for AVX-512F. At run time each kernel runs the twin of [`Simd::active`]:
//! the widest level the CPU has, or the level `RGBN_SIMD` names. The kernels with twins:
//! the RGBN bilateral filter ([`super::bilateral`]), the recursive Gaussian
//! ([`super::convolve::Deriche`]) and its row/lane transposes, the fused normal smoothing
//! ([`super::smooth`]) and the relit preview ([`crate::render::relight`]).
//!
//! `RGBN_SIMD=portable|avx2|avx512` forces a twin for every kernel, to measure one twin on a
//! machine that has a wider one or to rule a twin out when looking for a bug. Asking for a
//! level this CPU cannot run, or for an unknown name, is an error: the `rgbn` binary stops at
//! start-up with exit code 2 and a message naming `RGBN_SIMD` and what the CPU has
//! ([`from_env`]); the library, which cannot refuse to run, logs that message as a warning
//! once and runs the widest twin the CPU has.
//!
//! Results: a twin computes the same arithmetic as the portable one, so most are bit-identical
//! to it; where a twin uses fused multiply-adds (the bilateral filter) results differ by
//! rounding only (to [`super::bilateral::TWIN_TOLERANCE`]). The tests compare every twin this
//! CPU runs with the portable one, for every kernel with twins: the bilateral filter
//! (`bilateral::tests`, within that tolerance), the recursive Gaussian (`convolve_tests`), the
//! fused normal smoothing (`smooth::tests`) and the relit preview (`render::tests`), these
//! three bit for bit (the portable code compiled with wider instructions and no FMA).
//!
//! Tests choose a twin per call (the kernels take a [`Simd`] internally), never through the
//! environment, which is read once per process.

use std::sync::OnceLock;

/// The environment variable that forces a twin.
pub const ENV: &str = "RGBN_SIMD";

/// An instruction-set level for which kernels have a compiled twin (ordered: each level's CPUs
/// run the levels below it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Simd {
    /// The target's baseline instructions, no fused multiply-add.
    Portable,
    /// x86-64 AVX2 with FMA (256-bit vectors).
    Avx2,
    /// x86-64 AVX-512F, with AVX2 and FMA (512-bit vectors).
    Avx512,
}

impl Simd {
    /// Every level, narrowest first.
    pub const ALL: [Simd; 3] = [Simd::Portable, Simd::Avx2, Simd::Avx512];

    /// The name `RGBN_SIMD` takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Simd::Portable => "portable",
            Simd::Avx2 => "avx2",
            Simd::Avx512 => "avx512",
        }
    }

    /// The level named `s` (as [`Simd::name`], case and surrounding spaces ignored).
    #[must_use]
    pub fn parse(s: &str) -> Option<Simd> {
        let s = s.trim();
        Simd::ALL
            .into_iter()
            .find(|l| l.name().eq_ignore_ascii_case(s))
    }

    /// The widest level this CPU runs (detected once).
    #[must_use]
    pub fn detected() -> Simd {
        static DETECTED: OnceLock<Simd> = OnceLock::new();
        *DETECTED.get_or_init(detect)
    }

    /// Whether this CPU runs this level.
    #[must_use]
    pub fn supported(self) -> bool {
        self <= Simd::detected()
    }

    /// The levels this CPU runs, narrowest first (the tests compare each with the portable
    /// twin).
    pub fn supported_levels() -> impl Iterator<Item = Simd> {
        Simd::ALL.into_iter().filter(|l| l.supported())
    }

    /// Whether kernels run their twin of this level: [`Simd::active`] is this level or wider
    /// (so this CPU has its instructions). The dispatch of every kernel with twins.
    #[must_use]
    pub fn runs(self) -> bool {
        self <= Simd::active()
    }

    /// The level a kernel asked for `self` runs: `self`, or the widest this CPU has if it has
    /// not got `self` (a twin never runs on a CPU without its instructions).
    #[must_use]
    pub fn clamped(self) -> Simd {
        self.min(Simd::detected())
    }

    /// The level kernels run by default: `RGBN_SIMD`'s when it is set and this CPU runs it,
    /// else [`Simd::detected`]. Read once per process; a bad `RGBN_SIMD` is logged as a
    /// warning (module docs).
    #[must_use]
    pub fn active() -> Simd {
        static ACTIVE: OnceLock<Simd> = OnceLock::new();
        *ACTIVE.get_or_init(|| match from_env() {
            Ok(level) => level.unwrap_or_else(Simd::detected),
            Err(e) => {
                tracing::warn!("{e}; running the {} twins", Simd::detected());
                Simd::detected()
            }
        })
    }
}

impl std::fmt::Display for Simd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A bad `RGBN_SIMD`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SimdError {
    /// Not one of the names.
    #[error(
        "RGBN_SIMD={value:?} is not a twin: use portable, avx2 or avx512 \
         (this CPU runs up to {detected}), or unset it"
    )]
    Unknown {
        /// What the variable holds.
        value: String,
        /// The widest level this CPU runs.
        detected: Simd,
    },
    /// A level this CPU cannot run.
    #[error(
        "RGBN_SIMD={requested}: this CPU cannot run the {requested} twins (it has up to \
         {detected}: {}); set RGBN_SIMD to one of those or unset it",
        supported_list(*detected)
    )]
    Unsupported {
        /// The level asked for.
        requested: Simd,
        /// The widest level this CPU runs.
        detected: Simd,
    },
}

fn supported_list(detected: Simd) -> String {
    let names: Vec<&str> = Simd::ALL
        .into_iter()
        .filter(|l| *l <= detected)
        .map(Simd::name)
        .collect();
    names.join(", ")
}

/// `RGBN_SIMD` checked against this CPU: `None` when it is unset or empty. The `rgbn` binary
/// calls this at start-up and stops with exit code 2 on an error.
///
/// # Errors
/// An unknown name, or a level this CPU cannot run.
pub fn from_env() -> Result<Option<Simd>, SimdError> {
    match std::env::var_os(ENV) {
        None => Ok(None),
        Some(v) => check(&v.to_string_lossy(), Simd::detected()),
    }
}

/// [`from_env`] for the value `value` on a CPU whose widest level is `detected`.
fn check(value: &str, detected: Simd) -> Result<Option<Simd>, SimdError> {
    if value.trim().is_empty() {
        return Ok(None);
    }
    match Simd::parse(value) {
        None => Err(SimdError::Unknown {
            value: value.to_string(),
            detected,
        }),
        Some(l) if l > detected => Err(SimdError::Unsupported {
            requested: l,
            detected,
        }),
        Some(l) => Ok(Some(l)),
    }
}

#[cfg(target_arch = "x86_64")]
fn detect() -> Simd {
    let avx2 =
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma");
    if avx2 && std::arch::is_x86_feature_detected!("avx512f") {
        Simd::Avx512
    } else if avx2 {
        Simd::Avx2
    } else {
        Simd::Portable
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> Simd {
    Simd::Portable
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_and_order_is_by_width() {
        for l in Simd::ALL {
            assert_eq!(Simd::parse(l.name()), Some(l));
            assert_eq!(
                Simd::parse(&format!(" {} ", l.name().to_uppercase())),
                Some(l)
            );
        }
        assert_eq!(Simd::parse("sse"), None);
        assert!(Simd::Portable < Simd::Avx2 && Simd::Avx2 < Simd::Avx512);
        assert!(Simd::Portable.supported());
        assert_eq!(Simd::Avx512.clamped(), Simd::detected());
        assert_eq!(Simd::Portable.clamped(), Simd::Portable);
    }

    #[test]
    fn a_level_the_cpu_lacks_or_an_unknown_name_is_an_error_naming_the_variable() {
        assert_eq!(check("", Simd::Avx2), Ok(None));
        assert_eq!(check("avx2", Simd::Avx2), Ok(Some(Simd::Avx2)));
        assert_eq!(check("portable", Simd::Avx2), Ok(Some(Simd::Portable)));
        let e = check("avx512", Simd::Avx2).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("RGBN_SIMD=avx512") && msg.contains("portable, avx2"),
            "{msg}"
        );
        let e = check("neon", Simd::Portable).unwrap_err();
        assert!(matches!(e, SimdError::Unknown { .. }));
        assert!(e.to_string().contains("RGBN_SIMD=\"neon\""), "{e}");
    }
}
