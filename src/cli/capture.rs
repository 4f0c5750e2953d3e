//! `rgbn capture`: photometric stereo from photos + a light file to an RGBN EXR, and
//! (`--chrome`) light calibration from photos of a mirror sphere to a light file.

use super::error::{usage, CliError};
use super::out::Out;
use crate::capture::chrome::{calibrate_chrome, ChromeParams};
use crate::capture::inputs::{load_inputs, PhotoStack, PsInputSpec, Transfer};
use crate::capture::photometric::{photometric_stereo, PhotometricParams, PsMethod};
use crate::raster::gradient::GradientField;
use crate::raster::integrate::curl_interior;
use crate::raster::io;
use clap::{Args, ValueEnum};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Estimator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Woodham's least squares.
    Ls,
    /// Trimmed least squares (robust to shadows and highlights).
    Trimmed,
    /// L1 regression by iteratively reweighted least squares, from least squares.
    L1,
    /// Sparse Bayesian learning (Ikehata et al. 2012).
    Sbl,
}

#[derive(Args, Debug)]
pub struct CaptureArgs {
    /// Photos from one viewpoint, in light-row order (or matched by --names).
    #[arg(long, num_args = 1.., required_unless_present = "lp")]
    pub photos: Vec<PathBuf>,
    /// Light directions: one `x y z` row per light (x right, y up, z to the camera), optional
    /// count line first. Not used with --chrome.
    #[arg(long, required_unless_present_any = ["chrome", "lp"])]
    pub lights: Option<PathBuf>,
    /// An RTI light-position file (RTIBuilder / RelightLab `.lp`): a count line, then `NAME x y
    /// z` per photo (x right, y up, z to the camera; names relative to the file). Gives both the
    /// photos and their light directions.
    #[arg(long, conflicts_with_all = ["photos", "lights", "names", "chrome"])]
    pub lp: Option<PathBuf>,
    /// Per-light `r g b` intensities, same layout.
    #[arg(long)]
    pub intensities: Option<PathBuf>,
    /// File names, one per light row (DiLiGenT filenames.txt): photos are matched to rows by name.
    #[arg(long)]
    pub names: Option<PathBuf>,
    /// Object mask (white = object); required with --chrome (the sphere's mask).
    #[arg(long, required_if_eq("chrome", "true"))]
    pub mask: Option<PathBuf>,
    /// Estimator.
    #[arg(long, value_enum, default_value_t = MethodArg::Trimmed)]
    pub method: MethodArg,
    /// Shading exponent k of `I ∝ ρ (n·l)^k`: `auto` (default) estimates it from the photos
    /// (docs/capture.md), a number in [0.5, 2] fixes it (1 = Lambert, Woodham's model).
    #[arg(long, default_value = "auto", value_parser = parse_exponent)]
    pub exponent: Exponent,
    /// Photos are linear (raw) data (default).
    #[arg(long, conflicts_with = "srgb")]
    pub linear: bool,
    /// Photos are sRGB-encoded 8/16-bit files (decoded to linear).
    #[arg(long)]
    pub srgb: bool,
    /// Calibrate lights from photos of a chrome sphere instead; writes a light file.
    #[arg(long, conflicts_with_all = ["lights", "intensities", "names"])]
    pub chrome: bool,
    /// Output: RGBN EXR (photometric stereo) or a light text file (--chrome). Never an input.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    #[command(flatten)]
    pub exr: super::ExrArgs,
}

pub fn capture_cmd(a: &CaptureArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let transfer = if a.srgb {
        Transfer::Srgb
    } else {
        Transfer::Linear
    };
    let mut inputs: Vec<&Path> = a.photos.iter().map(PathBuf::as_path).collect();
    inputs.extend(
        [&a.lights, &a.lp, &a.intensities, &a.names, &a.mask]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path),
    );
    io::check_output(&a.output, &inputs)?;
    if a.chrome {
        let mask_path = a
            .mask
            .as_ref()
            .ok_or_else(|| usage("--chrome needs --mask (the sphere's mask)"))?;
        let stack = PhotoStack::load(&a.photos, transfer)?;
        let (w, h, mask) = io::load_mask(mask_path)?;
        if (w, h) != (stack.width, stack.height) {
            return Err(crate::RgbnError::SizeMismatch {
                what: "mask",
                want_w: stack.width,
                want_h: stack.height,
                got_w: w,
                got_h: h,
                path: mask_path.clone(),
            }
            .into());
        }
        let cal = calibrate_chrome(&stack, &mask, &ChromeParams::default())?;
        super::interrupt::check()?;
        io::write_atomic(&a.output, |f| {
            let mut s = format!(
                "# rgbn capture --chrome: sphere centre ({:.2}, {:.2}) px, radius {:.2} px\n{}\n",
                cal.centre_px[0],
                cal.centre_px[1],
                cal.radius_px,
                cal.directions.len()
            );
            for d in &cal.directions {
                s.push_str(&format!("{:.6} {:.6} {:.6}\n", d[0], d[1], d[2]));
            }
            f.write_all(s.as_bytes()).map_err(|e| e.to_string())
        })?;
        out.line(format_args!(
            "{} light directions (sphere at ({:.1}, {:.1}), radius {:.1} px) → {}",
            cal.directions.len(),
            cal.centre_px[0],
            cal.centre_px[1],
            cal.radius_px,
            a.output.display()
        ))?;
        return Ok(());
    }
    io::Format::of(&a.output)
        .ok()
        .filter(|f| *f == io::Format::Exr)
        .ok_or_else(|| {
            usage(format!(
                "the output must be an .exr (colour + normals + mask): {}",
                a.output.display()
            ))
        })?;
    let lights = match (&a.lp, &a.lights) {
        (Some(lp), _) => {
            if !crate::capture::lp::is_lp(lp) {
                return Err(usage(format!(
                    "--lp takes an RTI light-position file ending in .lp: {}",
                    lp.display()
                )));
            }
            lp.clone()
        }
        (None, l) => l.clone().unwrap_or_default(),
    };
    let spec = PsInputSpec {
        photos: a.photos.clone(),
        lights,
        intensities: a.intensities.clone(),
        names: a.names.clone(),
        mask: a.mask.clone(),
        transfer,
    };
    let ps = load_inputs(&spec)?;
    for note in &ps.notes {
        eprintln!("rgbn: note: {note}");
    }
    let params = PhotometricParams {
        method: match a.method {
            MethodArg::Ls => PsMethod::LeastSquares,
            MethodArg::Trimmed => PsMethod::Trimmed,
            MethodArg::L1 => PsMethod::L1,
            MethodArg::Sbl => PsMethod::Sbl,
        },
        exponent: match a.exponent {
            Exponent::Auto => None,
            Exponent::Fixed(k) => Some(k),
        },
        ..PhotometricParams::default()
    };
    let (img, rep) = photometric_stereo(&ps.stack, &ps.lights, ps.mask.as_deref(), &params)?;
    super::interrupt::check()?;
    io::save(&img, &a.output, &a.exr.save_options())?;
    let interior = img
        .mask()
        .map(|m| curl_interior(m, img.width(), img.height()));
    let curl = GradientField::from_normals(&img).curl_stats(interior.as_deref());
    out.line(format_args!(
        "{}×{} from {} photos: {} of {} pixels solved ({} dark, {} unsolvable, {} with saturated samples); shading exponent {:.3}{}; relative RMS curl {:.3e} (mask interior) → {}",
        img.width(),
        img.height(),
        ps.stack.photos.len(),
        rep.solved,
        rep.pixels,
        rep.dark,
        rep.unsolvable,
        rep.with_saturated,
        rep.exponent,
        if matches!(a.exponent, Exponent::Auto) {
            " (estimated)"
        } else {
            ""
        },
        curl.relative,
        a.output.display()
    ))?;
    Ok(())
}

/// `--exponent`: estimated from the photos, or fixed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exponent {
    Auto,
    Fixed(f32),
}

fn parse_exponent(s: &str) -> Result<Exponent, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(Exponent::Auto);
    }
    let (lo, hi) = crate::capture::photometric::EXPONENT_RANGE;
    match s.parse::<f32>() {
        Ok(k) if (lo..=hi).contains(&k) => Ok(Exponent::Fixed(k)),
        _ => Err(format!(
            "expected `auto` or a number in [{lo}, {hi}], got `{s}`"
        )),
    }
}
