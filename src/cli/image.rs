//! The image commands: `info`, `render`, `filter` (a part of [`crate::cli`]).

use super::error::{usage, CliError};
use super::out::Out;
use crate::error::RgbnError;
use crate::ops::filter::{filter_normals, filter_streamed, FilterOptions, FilterReport, Kernel};
use crate::raster::convolve::BorderMode;
use crate::raster::gradient::GradientField;
use crate::raster::integrate::{green_convention, green_convention_fractions, GreenVerdict};
use crate::raster::io::targets::{PngTarget, RowEncoding};
use crate::raster::io::{
    self, ExrPrecision, Format, InputSpec, LoadOptions, NormalConvention, SaveOptions,
};
use crate::raster::sample::demo_medallion;
use crate::raster::strips::{self, Opened, StreamInput};
use crate::raster::{RgbnImage, Validation};
use crate::render::{self, InspectParams, Light, Shading, View};
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};

/// Where the input comes from.
#[derive(Args, Debug, Clone)]
pub struct InputArgs {
    /// RGBN EXR (colour R,G,B + normal N.X,N.Y,N.Z [+ mask A]), a normal map (PNG/TIFF/EXR) or
    /// a Polynomial Texture Map (.ptm: LRGB or RGB, normals from the luminance maximum).
    pub file: Option<PathBuf>,
    /// Use the built-in demo medallion instead of a file.
    #[arg(long, conflicts_with_all = ["file", "normal"])]
    pub demo: bool,
    /// Side of the built-in demo in pixels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(16..=16384))]
    pub demo_size: u32,
    /// Colour image (PNG/JPEG/TIFF in sRGB, or linear EXR).
    #[arg(long)]
    pub color: Option<PathBuf>,
    /// Normal map (instead of FILE).
    #[arg(long, conflicts_with = "file")]
    pub normal: Option<PathBuf>,
    /// Coverage mask (greyscale image).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Input normal maps use the DirectX convention (green = −y).
    #[arg(long)]
    pub dx: bool,
    /// Read an EXR's R,G,B as the normal (Blender-style normal pass).
    #[arg(long)]
    pub exr_rgb_is_normal: bool,
    /// Refuse NaN/inf/zero-length normals instead of repairing them to (0,0,1).
    #[arg(long)]
    pub strict: bool,
}

#[derive(Args, Debug)]
pub struct InfoArgs {
    #[command(flatten)]
    pub input: InputArgs,
}

/// Relighting options shared by `render` and `publish`.
#[derive(Args, Debug, Clone)]
pub struct ShadingArgs {
    /// Light direction x,y,z towards the light (+x right, +y up, +z to the viewer). Repeat for
    /// several lights; default -0.5,0.6,0.8.
    #[arg(long = "light", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub lights: Vec<[f32; 3]>,
    /// Ambient light.
    #[arg(long, default_value_t = 0.08)]
    pub ambient: f32,
    /// Blinn-Phong specular strength (0 = Lambert only).
    #[arg(long, default_value_t = 0.25)]
    pub specular: f32,
    /// Blinn-Phong exponent.
    #[arg(long, default_value_t = 40.0)]
    pub shininess: f32,
    /// Exposure in stops.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,
}

impl ShadingArgs {
    /// The shading these options describe, checked (white lights; the default light when none
    /// is given).
    pub(super) fn shading(&self) -> Result<Shading, RgbnError> {
        let shading = Shading {
            lights: if self.lights.is_empty() {
                Shading::default().lights
            } else {
                self.lights.iter().map(|d| Light::white(*d)).collect()
            },
            ambient: self.ambient,
            specular: self.specular,
            shininess: self.shininess,
            exposure_ev: self.exposure,
        };
        shading.validate()?;
        Ok(shading)
    }
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub shading: ShadingArgs,
    /// What to show: relit, albedo, normals, curl, curvature, exaggerated, radiance_scaling,
    /// specular_enhancement, normal_unsharp, toon, lines, ambient_occlusion, multi_light (see
    /// --help for each view's reference and parameters).
    #[arg(long, default_value = "relit", long_help = view_help())]
    pub view: View,
    /// A view parameter NAME=VALUE (repeat for several), e.g. --param curvature_scale=20 or
    /// --param toon_levels=3; the names are prefixed by the view's short name.
    #[arg(long = "param", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub params: Vec<String>,
    /// Output PNG (8-bit sRGB with alpha).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Read and write row by row, with memory bounded by the strip (the relit, albedo and
    /// normals views of PNG, TIFF or EXR input): `auto` over 16 Mpx or the pixel limit, `always` insists
    /// (and says why not), `never` reads the image whole.
    #[arg(long, value_enum, default_value_t = StreamMode::Auto)]
    pub stream: StreamMode,
}

#[derive(Args, Debug)]
pub struct FilterArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Kernel, applied in order when repeated: gauss:SIGMA, box:R, sharpen:SIGMA,AMOUNT,
    /// edge:SIGMA_FINE,SIGMA_COARSE,AMOUNT, highpass:SIGMA, dog:SIGMA_FINE,SIGMA_COARSE,
    /// log:SIGMA, scale:FACTOR, sep:ROW/COL (comma lists), kernel:WxH:WEIGHTS.
    #[arg(
        long = "kernel",
        short = 'k',
        required = true,
        allow_hyphen_values = true
    )]
    pub kernels: Vec<String>,
    /// Border mode: mirror, clamp, wrap, zero.
    #[arg(long, default_value = "mirror")]
    pub border: BorderMode,
    /// Normalised convolution inside the mask (values outside never bleed in).
    #[arg(long)]
    pub mask_aware: bool,
    /// Output: .exr (colour + normals + mask) or .png/.tif (normal map).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write the colour here (.png sRGB or .exr linear).
    #[arg(long)]
    pub color_out: Option<PathBuf>,
    /// Bits per channel of PNG/TIFF output (8 or 16).
    #[arg(long, default_value_t = 16, value_parser = parse_bits)]
    pub bits: u8,
    /// Write normal maps in the DirectX convention.
    #[arg(long)]
    pub out_dx: bool,
    /// Write EXR as 16-bit half floats (the same as --exr-type f16).
    #[arg(long)]
    pub half: bool,
    #[command(flatten)]
    pub exr: super::ExrArgs,
    /// Read and write row by row, in strips, with memory bounded by the strip instead of the
    /// image: `auto` does for images over 16 Mpx (or the pixel limit) when it can (PNG, TIFF in strips or scan-line EXR in, PNG out, any border but
    /// wrap), `always` insists (and says why not), `never` reads the image whole.
    #[arg(long, value_enum, default_value_t = StreamMode::Auto)]
    pub stream: StreamMode,
    /// Rows per strip when streaming (default: 8 Mpx worth, at least 64 rows and four halos;
    /// the first three strips ramp up from an eighth).
    #[arg(long, value_name = "ROWS", value_parser = clap::value_parser!(u64).range(1..))]
    pub strip_rows: Option<u64>,
}

/// `--stream`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum StreamMode {
    /// Stream images over [`strips::AUTO_STREAM_PIXELS`] when the files allow.
    Auto,
    /// Stream whatever the size; refuse when the files do not allow it.
    Always,
    /// Read the image whole.
    Never,
}

impl StreamMode {
    /// Whether an image of `size` that can be streamed is: always, or in `auto` mode over
    /// [`strips::AUTO_STREAM_PIXELS`] or the pixel limit.
    pub(super) fn streams(self, (w, h): (usize, usize)) -> bool {
        let px = (w as u64) * (h as u64);
        match self {
            StreamMode::Always => true,
            StreamMode::Auto => px > strips::AUTO_STREAM_PIXELS || px > crate::raster::max_pixels(),
            StreamMode::Never => false,
        }
    }

    /// Whether a graph evaluation over an image of `size` that can be streamed is: always, or
    /// in `auto` mode from [`strips::AUTO_STREAM_GRAPH_PIXELS`] (a graph's strips overlap its
    /// reading, its operators and its writing, which a whole-image run does one after the
    /// other).
    pub(super) fn streams_graph(self, (w, h): (usize, usize)) -> bool {
        let px = (w as u64) * (h as u64);
        match self {
            StreamMode::Auto => px >= strips::AUTO_STREAM_GRAPH_PIXELS || self.streams((w, h)),
            _ => self.streams((w, h)),
        }
    }

    /// Refuses `always` when the work cannot stream, saying why (`why`).
    pub(super) fn allows(self, why: Option<&str>) -> Result<(), CliError> {
        match (self, why) {
            (StreamMode::Always, Some(why)) => {
                Err(usage(format!("--stream always: cannot stream: {why}")))
            }
            _ => Ok(()),
        }
    }
}

/// `--view`'s long help: every view with its documentation and parameters.
fn view_help() -> String {
    format!(
        "What to show. Each view, its reference and its parameters (set with --param \
         NAME=VALUE):\n\n{}",
        InspectParams::help()
    )
}

fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<f32>()
                .map_err(|_| format!("{t:?} is not a number"))
        })
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => Err(format!("expected x,y,z (three numbers), got {s:?}")),
    }
}

fn parse_bits(s: &str) -> Result<u8, String> {
    match s {
        "8" => Ok(8),
        "16" => Ok(16),
        _ => Err(format!("{s:?}: bits must be 8 or 16")),
    }
}

impl InputArgs {
    pub(super) fn spec(&self) -> InputSpec {
        InputSpec {
            rgbn: self.file.clone(),
            color: self.color.clone(),
            normal: self.normal.clone(),
            mask: self.mask.clone(),
        }
    }

    pub(super) fn load_options(&self) -> LoadOptions {
        LoadOptions::of_flags(self.dx, self.exr_rgb_is_normal, self.strict)
    }

    /// Loads the input (or builds the demo) and reports repairs on stderr.
    pub(super) fn load(&self) -> Result<(RgbnImage, String), CliError> {
        if self.demo {
            let mut img = demo_medallion(self.demo_size as usize);
            let spec = self.spec();
            if let Some(c) = &spec.color {
                let (w, h, color) = io::load_color(c)?;
                if (w, h) != (img.width(), img.height()) {
                    return Err(RgbnError::SizeMismatch {
                        what: "colour image",
                        want_w: img.width(),
                        want_h: img.height(),
                        got_w: w,
                        got_h: h,
                        path: c.clone(),
                    }
                    .into());
                }
                img.set_color(color)?;
            }
            return Ok((img, format!("built-in demo {0}×{0}", self.demo_size)));
        }
        let spec = self.spec();
        if spec.rgbn.is_none() && spec.normal.is_none() {
            return Err(usage(
                "no input: give FILE (an RGBN EXR, a normal map or a .ptm), --normal PATH, or --demo",
            ));
        }
        let loaded = io::load(&spec, &self.load_options())?;
        let r = loaded.repaired;
        let name = spec
            .rgbn
            .as_ref()
            .or(spec.normal.as_ref())
            .expect("checked above")
            .display()
            .to_string();
        note_repairs(&r, &Some(PathBuf::from(&name)));
        Ok((loaded.image, name))
    }

    pub(super) fn paths(&self) -> Vec<&Path> {
        [&self.file, &self.color, &self.normal, &self.mask]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .collect()
    }
}

pub(super) fn info(a: &InfoArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let (img, name) = a.input.load()?;
    let v = img.validate();
    // `load` repaired the image; report what the file held.
    let before = if a.input.demo {
        v
    } else {
        io::load(
            &a.input.spec(),
            &LoadOptions {
                strict: false,
                ..a.input.load_options()
            },
        )?
        .repaired
    };
    let g = GradientField::from_normals(&img);
    let c = g.curl_stats_of(crate::raster::gradient::Differences::Averaged, img.mask());
    let (w, h) = (img.width(), img.height());
    out.line(format_args!("input:       {name}"))?;
    out.line(format_args!(
        "size:        {w}×{h} ({:.2} Mpx)",
        (w * h) as f64 / 1e6
    ))?;
    out.line(format_args!(
        "channels:    colour RGB (linear), normal XYZ, mask {}",
        if img.mask().is_some() { "yes" } else { "no" }
    ))?;
    out.line(format_args!(
        "validation:  {} non-finite colour, {} non-finite normals, {} zero-length, {} not unit length, {} back-facing (n_z ≤ 0)",
        before.non_finite_color,
        before.non_finite_normal,
        before.zero_length_normal,
        before.non_unit,
        before.back_facing
    ))?;
    out.line(format_args!(
        "gradient:    {} pixels with n_z < 1e-3 clamped; RMS |g| = {:.4}",
        g.clamped, c.rms_gradient
    ))?;
    out.line(format_args!(
        "curl:        relative RMS {:.3e} (RMS {:.3e}, max |c| {:.3e})",
        c.relative, c.rms_curl, c.max_abs_curl
    ))?;
    let [as_read, flipped] = green_convention_fractions(&img)?;
    out.line(format_args!(
        "integrability: non-integrable fraction F = {as_read:.3e} (0: the normals of a surface; √(2/π) ≈ 0.80: noise); with green flipped F = {flipped:.3e}"
    ))?;
    let g = green_convention(&img);
    let hint = match g.verdict {
        GreenVerdict::DirectX if a.input.dx => " — load it without --dx",
        GreenVerdict::DirectX => " — load it with --dx",
        _ => "",
    };
    out.line(format_args!(
        "green:       {}{hint}",
        g.describe_loaded(a.input.dx)
    ))?;
    Ok(())
}

pub(super) fn render_cmd(a: &RenderArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    io::check_output(&a.output, &a.input.paths())?;
    if Format::of(&a.output)? != Format::Png {
        return Err(RgbnError::UnsupportedFormat {
            format: a
                .output
                .extension()
                .map(|e| e.to_string_lossy().into_owned())
                .unwrap_or_default(),
            path: a.output.clone(),
        }
        .into());
    }
    let shading = a.shading.shading()?;
    let params = InspectParams::from_assignments(&a.params)?;
    for p in &a.params {
        let name = p.split_once('=').map_or(p.as_str(), |(n, _)| n.trim());
        if let Some(v) = InspectParams::view_of(name).filter(|v| *v != a.view) {
            return Err(usage(format!(
                "--param {name} belongs to the {} view, not {} (use --view {})",
                v.name(),
                a.view.name(),
                v.name()
            )));
        }
    }
    // The per-pixel views stream (no pixel reads a neighbour); the others read whole.
    let why_whole = if a.input.demo {
        Some("the input is the built-in demo".to_string())
    } else if !matches!(a.view, View::Relit | View::Albedo | View::Normals) {
        Some(format!(
            "the {} view reads neighbourhoods or whole-image statistics (only relit, albedo and normals stream)",
            a.view.name()
        ))
    } else if a.stream == StreamMode::Never {
        None
    } else {
        match StreamInput::open(&a.input.spec(), &a.input.load_options())? {
            Opened::Whole(why) => Some(why),
            Opened::Stream(input) => {
                if a.stream.streams(input.size()) {
                    return render_stream(a, *input, &shading, &params, out);
                }
                None
            }
        }
    };
    a.stream.allows(why_whole.as_deref())?;
    let img = load_or_say_why(&a.input, why_whole)?;
    let rgba = render::render_with(&img, a.view, &shading, &params)?;
    super::interrupt::check()?;
    if a.view == View::Curvature {
        let scale = render::curvature_scale(&img, params.curvature_scale as f32);
        let text = scale.to_string();
        io::write_png8_text(
            &rgba,
            img.width(),
            img.height(),
            &[("rgbn:curvature_scale", &text)],
            &a.output,
        )?;
        out.line(format_args!(
            "curvature scale: {text} px (full colour at |H| = {:.4e} /px)",
            1.0 / scale
        ))?;
    } else {
        io::write_raster8(&rgba, img.width(), img.height(), 4, Format::Png, &a.output)?;
    }
    out.line(format_args!(
        "wrote {} ({}×{}, {}): {}",
        a.view.name(),
        img.width(),
        img.height(),
        "sRGB 8-bit",
        a.output.display()
    ))?;
    Ok(())
}

/// `rgbn render` of a per-pixel view, streamed: PNG, TIFF or EXR rows in, RGBA rows out ([`strips`]).
fn render_stream(
    a: &RenderArgs,
    mut input: StreamInput,
    shading: &Shading,
    params: &InspectParams,
    out: &mut Out<'_>,
) -> Result<(), CliError> {
    let (w, h) = input.size();
    let mut target = PngTarget::create_rgba8(&a.output, w, h)?;
    let repaired = {
        let mut rows = target.rows(RowEncoding::Srgb)?;
        let mut rgba = Vec::new();
        let strip = strips::strip_rows(w, 0);
        let r = strips::for_each_strip_image(&mut input, 0, strip, |img, _, _| {
            super::interrupt::check()?;
            rgba.resize(img.len() * 4, 0);
            render::render_with_into(img, a.view, shading, params, &mut rgba)?;
            rows.write_rgba8(&rgba)?;
            Ok::<(), CliError>(())
        })?;
        rows.finish()?;
        r
    };
    target.commit()?;
    note_repairs(&repaired, &a.input.spec().normal.or(a.input.file.clone()));
    out.line(format_args!(
        "wrote {} ({w}×{h}, sRGB 8-bit, streamed): {}",
        a.view.name(),
        a.output.display()
    ))?;
    Ok(())
}

/// Loads the input whole; a refusal for size says why it had to be read whole (`why`).
fn load_or_say_why(input: &InputArgs, why: Option<String>) -> Result<RgbnImage, CliError> {
    match input.load() {
        Ok((img, _)) => Ok(img),
        Err(CliError::Rgbn(e @ RgbnError::TooLarge { .. })) => Err(match why {
            Some(why) => usage(format!(
                "{e}; working on it without reading it whole needs PNG, TIFF or scan-line EXR in and PNG out, but {why}"
            )),
            None => e.into(),
        }),
        Err(e) => Err(e),
    }
}

pub(super) fn filter_cmd(a: &FilterArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let kernels: Vec<Kernel> = a
        .kernels
        .iter()
        .map(|k| Kernel::parse(k))
        .collect::<Result<_, _>>()?;
    let inputs = a.input.paths();
    io::check_output(&a.output, &inputs)?;
    Format::of(&a.output)?;
    if let Some(c) = &a.color_out {
        io::check_output(c, &inputs)?;
        Format::of(c)?;
        if c == &a.output {
            return Err(usage(format!(
                "--color-out and --output name the same file: {}",
                c.display()
            )));
        }
    }
    let opts = FilterOptions {
        border: a.border,
        mask_aware: a.mask_aware,
    };
    let convention = if a.out_dx {
        NormalConvention::DirectX
    } else {
        NormalConvention::OpenGl
    };
    // Streamed when it can be and should be; else whole, and a refusal for size says why.
    let mut why_whole = None;
    if a.input.demo {
        why_whole = Some("the input is the built-in demo".to_string());
    } else if a.stream != StreamMode::Never {
        let png = |p: &Path| Format::of(p).is_ok_and(|f| f == Format::Png);
        match StreamInput::open(&a.input.spec(), &a.input.load_options())? {
            Opened::Whole(why) => why_whole = Some(why),
            Opened::Stream(_) if a.border == BorderMode::Wrap => {
                why_whole = Some("the wrap border reads the opposite edge of the image".into());
            }
            Opened::Stream(_)
                if !png(&a.output) || a.color_out.as_deref().is_some_and(|c| !png(c)) =>
            {
                why_whole = Some("the output is not a PNG (only PNG is written row by row)".into());
            }
            Opened::Stream(input) => {
                if a.stream.streams(input.size()) {
                    return filter_stream(a, *input, &kernels, &opts, convention, out);
                }
            }
        }
    }
    a.stream.allows(why_whole.as_deref())?;
    let img = load_or_say_why(&a.input, why_whole)?;
    let (filtered, report) = filter_normals(&img, &kernels, &opts)?;
    let save = SaveOptions {
        bits: a.bits,
        convention,
        precision: if a.half {
            ExrPrecision::Half
        } else {
            a.exr.exr_type
        },
        compression: a.exr.exr_compression,
        zarr: a.exr.zarr_options(),
    };
    super::interrupt::check()?;
    io::save(&filtered, &a.output, &save)?;
    if let Some(c) = &a.color_out {
        io::save_color(&filtered, c, a.bits)?;
    }
    filter_summary(a, &kernels, &report, out)
}

/// `rgbn filter` streamed: PNG, TIFF or EXR rows in, strips filtered, PNG rows out ([`strips`]).
fn filter_stream(
    a: &FilterArgs,
    mut input: StreamInput,
    kernels: &[Kernel],
    opts: &FilterOptions,
    convention: NormalConvention,
    out: &mut Out<'_>,
) -> Result<(), CliError> {
    let (w, h) = input.size();
    let mut normals = PngTarget::create(&a.output, w, h, a.bits)?;
    let mut colour = match &a.color_out {
        Some(c) => Some(PngTarget::create(c, w, h, a.bits)?),
        None => None,
    };
    let (report, repaired) = {
        let mut nrows = normals.rows(RowEncoding::Normal(convention))?;
        let mut crows = match colour.as_mut() {
            Some(t) => Some(t.rows(RowEncoding::Srgb)?),
            None => None,
        };
        let mut albedo = Vec::new();
        let strip = a.strip_rows.map(|r| r as usize);
        let r = filter_streamed(&mut input, kernels, opts, strip, |win, n| {
            super::interrupt::check()?;
            nrows.write(n)?;
            if let Some(c) = crows.as_mut() {
                match win.color {
                    Some(col) => c.write(col.map(|p| win.core_of(p)))?,
                    None => {
                        albedo.resize(n[0].len(), io::DEFAULT_ALBEDO);
                        c.write([&albedo[..], &albedo[..], &albedo[..]])?;
                    }
                }
            }
            Ok::<(), CliError>(())
        })?;
        nrows.finish()?;
        if let Some(c) = crows {
            c.finish()?;
        }
        r
    };
    normals.commit()?;
    if let Some(c) = colour {
        c.commit()?;
    }
    note_repairs(&repaired, &a.input.spec().normal.or(a.input.file.clone()));
    filter_summary(a, kernels, &report, out)
}

/// The note `InputArgs::load` prints when normals were repaired.
pub(super) fn note_repairs(r: &Validation, name: &Option<PathBuf>) {
    let name = name
        .as_deref()
        .unwrap_or(Path::new(""))
        .display()
        .to_string();
    if let Some(note) = r.repair_note(&name) {
        eprintln!("rgbn: note: {note}");
    }
}

/// The line `rgbn filter` ends with.
fn filter_summary(
    a: &FilterArgs,
    kernels: &[Kernel],
    report: &FilterReport,
    out: &mut Out<'_>,
) -> Result<(), CliError> {
    let names: Vec<String> = kernels.iter().map(ToString::to_string).collect();
    out.line(format_args!(
        "filtered with {} ({} border{}): relative RMS curl {:.3e} → {:.3e}; {} pixels clamped; wrote {}",
        names.join(" then "),
        a.border.name(),
        if a.mask_aware { ", mask-aware" } else { "" },
        report.curl_before.relative,
        report.curl_after.relative,
        report.clamped,
        a.output.display()
    ))?;
    Ok(())
}
