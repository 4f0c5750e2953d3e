//! The command line (used by the `rgbn` binary).
//!
//! - this file: the command tree and [`run`], which dispatches and handles every error once;
//! - [`error`]: [`CliError`] and the one mapping to exit codes (0 ok, 1 evaluation failure,
//!   2 bad usage or input); errors are printed once, as one line on stderr:
//!   `rgbn: <what is wrong>: <file>`;
//! - [`out`]: the one writer for stdout (a closed pipe is not an error);
//! - `image`: `info`, `render`, `filter`; `publish`: `publish`; `serve`: `serve`; `graph`: `eval`, `batch`, `check`, `ops`;
//!   `capture`: `capture`; `docs`: `completions`, `man`.

use clap::{Parser, Subcommand};
#[cfg(feature = "gui")]
use std::path::PathBuf;

mod capture;
mod docs;
pub mod error;
mod exr;
mod graph;
mod image;
pub mod interrupt;
mod ops;
pub mod out;
mod png_sink;
mod publish;
mod serve;

pub use capture::CaptureArgs;
pub use docs::{CompletionsArgs, ManArgs};
pub use error::{CliError, Exit};
pub use exr::ExrArgs;
pub use graph::{apply_sets, parse_inputs, BatchArgs, CheckArgs, EvalArgs};
pub use image::{FilterArgs, InfoArgs, InputArgs, RenderArgs};
use out::Out;
pub use publish::PublishArgs;
pub use serve::ServeArgs;

/// Edit RGBN images (colour + normals) without breaking integrability.
///
/// With no command, the editor opens (when built with the `gui` feature): on the demo graph,
/// or on FILE as `rgbn edit FILE` does.
#[derive(Parser, Debug)]
#[command(name = "rgbn", version, about, long_about = None)]
#[cfg_attr(not(feature = "gui"), command(arg_required_else_help = true))]
#[cfg_attr(feature = "gui", command(args_conflicts_with_subcommands = true))]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    /// `rgbn FILE`: the editor on a graph or an image.
    #[cfg(feature = "gui")]
    #[command(flatten)]
    pub open: EditArgs,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Print size, channels, validation counts and integrability (curl) of an image.
    Info(InfoArgs),
    /// Relight an image (or show normals, albedo or curl) to an sRGB PNG.
    Render(RenderArgs),
    /// Filter the normals through their gradients with linear kernels.
    Filter(FilterArgs),
    /// Write a web folder (Deep Zoom tiles + a WebGL2 viewer) that relights the image.
    Publish(PublishArgs),
    /// Serve a folder (e.g. one `rgbn publish` wrote) on 127.0.0.1 only.
    Serve(ServeArgs),
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
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    Completions(CompletionsArgs),
    /// Print the man page (roff), or write one page per command into a folder with -o.
    Man(ManArgs),
    /// Open the editor on a graph file, or on an image in a new graph (the demo graph when no
    /// file is given).
    #[cfg(feature = "gui")]
    Edit(EditArgs),
}

/// Arguments of `rgbn edit`.
#[cfg(feature = "gui")]
#[derive(clap::Args, Debug)]
pub struct EditArgs {
    /// A graph file (.ron), or an image to open on a new, unsaved graph: a normal map (PNG,
    /// JPEG, TIFF, EXR), an RGBN EXR or a PTM. Default: `graphs/demo.ron`, or the built-in
    /// demo graph.
    pub file: Option<PathBuf>,
    /// Colour image of the opened image (PNG/JPEG/TIFF in sRGB, or linear EXR).
    #[arg(long)]
    pub color: Option<PathBuf>,
    /// Coverage mask of the opened image (greyscale image).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// The opened normal map uses the DirectX convention (green = −y).
    #[arg(long)]
    pub dx: bool,
    /// Read the opened EXR's R,G,B as the normal (Blender-style normal pass).
    #[arg(long)]
    pub exr_rgb_is_normal: bool,
    /// Memory budget for the images the editor keeps (value cache, viewport tiles, thumbnails,
    /// freed blocks kept for reuse), e.g. `4G`, `1536M`; least recently used values go first.
    /// Default: `RGBN_EDITOR_MEMORY`, else a quarter of the physical memory.
    #[arg(long, value_name = "SIZE")]
    pub memory: Option<String>,
}

#[cfg(feature = "gui")]
impl EditArgs {
    /// What the editor opens on, or a one-line error.
    pub fn start(&self) -> Result<crate::app::start::Start, CliError> {
        crate::app::start::Start::of(
            self.file.as_deref(),
            crate::app::start::ImageStart {
                path: PathBuf::new(),
                color: self.color.clone(),
                mask: self.mask.clone(),
                dx: self.dx,
                exr_rgb_is_normal: self.exr_rgb_is_normal,
            },
        )
        .map_err(error::usage)
    }
}

/// Parses `args` and runs; returns the process exit code. Prints errors on stderr.
pub fn run<I, T>(args: I) -> Exit
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let result = Cli::try_parse_from(args)
        .map_err(CliError::from)
        .and_then(|cli| match cli.command {
            // The editor prints nothing through `out` (and its threads may print): no lock.
            #[cfg(feature = "gui")]
            None => edit(&cli.open),
            #[cfg(feature = "gui")]
            Some(Command::Edit(a)) => edit(&a),
            #[cfg(not(feature = "gui"))]
            None => {
                // `arg_required_else_help` prints help; reached only with global flags.
                let _ = <Cli as clap::CommandFactory>::command().print_help();
                Err(error::usage("no command given"))
            }
            Some(command) => {
                // A command runs once and exits: freed scratch memory is kept for reuse (the
                // editor, which runs for hours, leaves the allocator as it is).
                // `RGBN_KEEP_FREED=0` turns this off, for measuring it.
                if std::env::var_os("RGBN_KEEP_FREED").is_none_or(|v| v != "0") {
                    crate::recycle::keep_freed_memory();
                }
                // Files replaced by outputs are freed after the process exits, not in the
                // commit (`RGBN_FREE_REPLACED=0`: at once, for measuring it).
                if std::env::var_os("RGBN_FREE_REPLACED").is_none_or(|v| v != "0") {
                    crate::raster::io::targets::replaced::free_replaced_after_exit();
                }
                interrupt::install();
                let stdout = std::io::stdout();
                let mut lock = stdout.lock();
                let mut out = Out::new(&mut lock);
                run_command(command, &mut out).and_then(|()| out.flush())
            }
        });
    match result {
        Ok(()) => Exit::Ok,
        // Whatever stopped the command (a cancelled evaluation, a refused write), a signal
        // received on the way is the reason to report.
        Err(e) => match interrupt::received() {
            Some(signal) => error::report(&CliError::Interrupted { signal }),
            None => error::report(&e),
        },
    }
}

/// Runs one command, printing its results to `out`.
///
/// # Errors
/// Whatever the command fails with; [`CliError::exit`] gives its exit code.
pub fn run_command(command: Command, out: &mut Out<'_>) -> Result<(), CliError> {
    match command {
        Command::Info(a) => image::info(&a, out),
        Command::Render(a) => image::render_cmd(&a, out),
        Command::Filter(a) => image::filter_cmd(&a, out),
        Command::Publish(a) => publish::publish_cmd(&a, out),
        Command::Serve(a) => serve::serve_cmd(&a, out),
        Command::Eval(a) => graph::eval_cmd(&a, out),
        Command::Batch(a) => graph::batch_cmd(&a, out),
        Command::Check(a) => ops::check_cmd(&a, out),
        Command::Ops => ops::ops_cmd(out),
        Command::Capture(a) => capture::capture_cmd(&a, out),
        Command::Completions(a) => docs::completions_cmd(&a, out),
        Command::Man(a) => docs::man_cmd(&a, out),
        #[cfg(feature = "gui")]
        Command::Edit(a) => edit(&a),
    }
}

/// Runs the editor on what `a` names (a bad file is refused before a window opens).
#[cfg(feature = "gui")]
fn edit(a: &EditArgs) -> Result<(), CliError> {
    if let Some(m) = &a.memory {
        let b = crate::app::memory::parse_budget(m)
            .map_err(|e| CliError::Usage(format!("--memory {e}")))?;
        crate::app::memory::set_budget(b);
    }
    crate::app::memory::budget().map_err(CliError::Usage)?;
    let start = a.start()?;
    crate::app::run(&start).map_err(CliError::Editor)
}
