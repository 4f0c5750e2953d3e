//! The command line. Exit codes: 0 success, 1 evaluation failure, 2 bad usage or bad input.
//! Errors are printed once, as one line on stderr: `rgbn: <what is wrong>: <file>`.

use crate::error::RgbnError;
use crate::ops::filter::{filter_normals, FilterOptions, Kernel};
use crate::raster::convolve::BorderMode;
use crate::raster::gradient::GradientField;
use crate::raster::io::{
    self, ExrPrecision, Format, InputSpec, LoadOptions, NormalConvention, SaveOptions,
};
use crate::raster::sample::demo_medallion;
use crate::raster::RgbnImage;
use crate::render::{self, Light, Shading, View};
use clap::{Args, Parser, Subcommand};
use std::io::Write;
use std::path::{Path, PathBuf};

#[path = "cli_graph.rs"]
mod graph_cmds;
pub use graph_cmds::{BatchArgs, CheckArgs, EvalArgs};

#[path = "cli_capture.rs"]
mod capture_cmds;
pub use capture_cmds::CaptureArgs;

/// Edit RGBN images (colour + normals) without breaking integrability.
///
/// With no command, the editor opens on the demo graph (when built with the `gui` feature).
#[derive(Parser, Debug)]
#[command(name = "rgbn", version, about, long_about = None)]
#[cfg_attr(not(feature = "gui"), command(arg_required_else_help = true))]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Print size, channels, validation counts and integrability (curl) of an image.
    Info(InfoArgs),
    /// Relight an image (or show normals, albedo or curl) to an sRGB PNG.
    Render(RenderArgs),
    /// Filter the normals through their gradients with linear kernels.
    Filter(FilterArgs),
    /// Evaluate a graph file: bind inputs, set parameters, write outputs.
    Eval(EvalArgs),
    /// Run a graph over many files (a glob), continuing past failures.
    Batch(BatchArgs),
    /// Validate a graph file without evaluating it.
    Check(CheckArgs),
    /// List every operator with its doc, ports and parameters.
    Ops,
    /// Photometric stereo: photos + lights → RGBN EXR; or --chrome: chrome-sphere photos → lights.
    Capture(CaptureArgs),
    /// Open the editor on a graph file (the demo graph when none is given).
    #[cfg(feature = "gui")]
    Edit(EditArgs),
}

/// Arguments of `rgbn edit`.
#[cfg(feature = "gui")]
#[derive(Args, Debug)]
pub struct EditArgs {
    /// The graph file to open (default: `graphs/demo.ron`, or the built-in demo graph).
    pub graph: Option<PathBuf>,
}

/// Where the input comes from.
#[derive(Args, Debug, Clone)]
pub struct InputArgs {
    /// RGBN EXR (colour R,G,B + normal N.X,N.Y,N.Z [+ mask A]) or a normal map (PNG/TIFF/EXR).
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

#[derive(Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub input: InputArgs,
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
    /// What to show: relit, albedo, normals, curl.
    #[arg(long, default_value = "relit")]
    pub view: View,
    /// Output PNG (8-bit sRGB with alpha).
    #[arg(short, long)]
    pub output: PathBuf,
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
    /// Write EXR as 16-bit half floats.
    #[arg(long)]
    pub half: bool,
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

/// A failure and the exit code it maps to.
#[derive(Debug)]
pub struct Failure {
    /// Process exit code (1 evaluation failure, 2 usage or input error).
    pub code: u8,
    /// One line: what is wrong, then where.
    pub message: String,
}

impl From<RgbnError> for Failure {
    fn from(e: RgbnError) -> Self {
        let code = match e {
            RgbnError::InvalidImage(_) => 1,
            _ => 2,
        };
        Failure {
            code,
            message: e.to_string(),
        }
    }
}

/// Parses `args` and runs; returns the process exit code. Prints errors on stderr.
pub fn run<I, T>(args: I) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return code;
        }
    };
    let Some(command) = cli.command else {
        #[cfg(feature = "gui")]
        {
            return edit(None);
        }
        // `arg_required_else_help` prints help; reached only with global flags and no command.
        #[cfg(not(feature = "gui"))]
        {
            let _ = <Cli as clap::CommandFactory>::command().print_help();
            return 2;
        }
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let result = match command {
        Command::Info(a) => info(&a, &mut out),
        Command::Render(a) => render_cmd(&a, &mut out),
        Command::Filter(a) => filter_cmd(&a, &mut out),
        Command::Eval(a) => graph_cmds::eval_cmd(&a, &mut out),
        Command::Batch(a) => graph_cmds::batch_cmd(&a, &mut out),
        Command::Check(a) => graph_cmds::check_cmd(&a, &mut out),
        Command::Ops => graph_cmds::ops_cmd(&mut out),
        Command::Capture(a) => capture_cmds::capture_cmd(&a, &mut out),
        #[cfg(feature = "gui")]
        Command::Edit(a) => {
            drop(out);
            return edit(a.graph);
        }
    };
    match result {
        Ok(()) => 0,
        Err(f) => {
            eprintln!("rgbn: {}", f.message);
            f.code
        }
    }
}

/// Runs the editor; returns the exit code.
#[cfg(feature = "gui")]
fn edit(graph: Option<PathBuf>) -> u8 {
    match crate::app::run(graph) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("rgbn: {e}");
            2
        }
    }
}

/// Writes a line to stdout; a closed pipe (e.g. `| head`) is not an error.
macro_rules! say {
    ($out:expr, $($t:tt)*) => {
        match writeln!($out, $($t)*) {
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(()),
            _ => {}
        }
    };
}

impl InputArgs {
    fn spec(&self) -> InputSpec {
        InputSpec {
            rgbn: self.file.clone(),
            color: self.color.clone(),
            normal: self.normal.clone(),
            mask: self.mask.clone(),
        }
    }

    fn load_options(&self) -> LoadOptions {
        LoadOptions {
            convention: if self.dx {
                NormalConvention::DirectX
            } else {
                NormalConvention::OpenGl
            },
            exr_rgb_is_normal: self.exr_rgb_is_normal,
            strict: self.strict,
        }
    }

    /// Loads the input (or builds the demo) and reports repairs on stderr.
    fn load(&self) -> Result<(RgbnImage, String), Failure> {
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
            return Err(Failure {
                code: 2,
                message:
                    "no input: give FILE (an RGBN EXR or a normal map), --normal PATH, or --demo"
                        .into(),
            });
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
        if !r.is_clean() {
            eprintln!(
                "rgbn: note: repaired {} NaN/inf and {} zero-length normals (now (0,0,1)), renormalised {}, zeroed {} non-finite colour values: {name}",
                r.non_finite_normal, r.zero_length_normal, r.non_unit, r.non_finite_color
            );
        }
        Ok((loaded.image, name))
    }

    fn paths(&self) -> Vec<&Path> {
        [&self.file, &self.color, &self.normal, &self.mask]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .collect()
    }
}

fn info(a: &InfoArgs, out: &mut impl Write) -> Result<(), Failure> {
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
    let c = g.curl_stats(img.mask());
    let (w, h) = (img.width(), img.height());
    say!(out, "input:       {name}");
    say!(
        out,
        "size:        {w}×{h} ({:.2} Mpx)",
        (w * h) as f64 / 1e6
    );
    say!(
        out,
        "channels:    colour RGB (linear), normal XYZ, mask {}",
        if img.mask().is_some() { "yes" } else { "no" }
    );
    say!(
        out,
        "validation:  {} non-finite colour, {} non-finite normals, {} zero-length, {} not unit length, {} back-facing (n_z ≤ 0)",
        before.non_finite_color,
        before.non_finite_normal,
        before.zero_length_normal,
        before.non_unit,
        before.back_facing
    );
    say!(
        out,
        "gradient:    {} pixels with n_z < 1e-3 clamped; RMS |g| = {:.4}",
        g.clamped,
        c.rms_gradient
    );
    say!(
        out,
        "curl:        relative RMS {:.3e} (RMS {:.3e}, max |c| {:.3e})",
        c.relative,
        c.rms_curl,
        c.max_abs_curl
    );
    Ok(())
}

fn render_cmd(a: &RenderArgs, out: &mut impl Write) -> Result<(), Failure> {
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
    let shading = Shading {
        lights: if a.lights.is_empty() {
            Shading::default().lights
        } else {
            a.lights.iter().map(|d| Light::white(*d)).collect()
        },
        ambient: a.ambient,
        specular: a.specular,
        shininess: a.shininess,
        exposure_ev: a.exposure,
    };
    shading.validate()?;
    let (img, _) = a.input.load()?;
    let rgba = render::render(&img, a.view, &shading)?;
    io::write_raster8(&rgba, img.width(), img.height(), 4, Format::Png, &a.output)?;
    say!(
        out,
        "wrote {} ({}×{}, {}): {}",
        a.view.name(),
        img.width(),
        img.height(),
        "sRGB 8-bit",
        a.output.display()
    );
    Ok(())
}

fn filter_cmd(a: &FilterArgs, out: &mut impl Write) -> Result<(), Failure> {
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
            return Err(Failure {
                code: 2,
                message: format!(
                    "--color-out and --output name the same file: {}",
                    c.display()
                ),
            });
        }
    }
    let (img, _) = a.input.load()?;
    let opts = FilterOptions {
        border: a.border,
        mask_aware: a.mask_aware,
    };
    let (filtered, report) = filter_normals(&img, &kernels, &opts)?;
    let save = SaveOptions {
        bits: a.bits,
        convention: if a.out_dx {
            NormalConvention::DirectX
        } else {
            NormalConvention::OpenGl
        },
        precision: if a.half {
            ExrPrecision::Half
        } else {
            ExrPrecision::Full
        },
    };
    io::save(&filtered, &a.output, &save)?;
    if let Some(c) = &a.color_out {
        io::save_color(&filtered, c, a.bits)?;
    }
    let names: Vec<String> = kernels.iter().map(ToString::to_string).collect();
    say!(
        out,
        "filtered with {} ({} border{}): relative RMS curl {:.3e} → {:.3e}; {} pixels clamped; wrote {}",
        names.join(" then "),
        a.border.name(),
        if a.mask_aware { ", mask-aware" } else { "" },
        report.curl_before.relative,
        report.curl_after.relative,
        report.clamped,
        a.output.display()
    );
    Ok(())
}
