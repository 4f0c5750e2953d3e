//! The `rgbn` binary: the command line (and, with the `gui` feature, the editor).
//!
//! The binary's edge: it sets up logging, runs [`rgbn::cli::run`] (which handles every error
//! once and maps it to the exit code) and exits with that code.

use std::io::IsTerminal;
use std::process::ExitCode;
use tracing_subscriber::filter::{EnvFilter, LevelFilter};
use tracing_subscriber::fmt::format::{FormatEvent, FormatFields, Writer};
use tracing_subscriber::fmt::FmtContext;
use tracing_subscriber::registry::LookupSpan;

/// Image-sized blocks are recycled between evaluations (see [`rgbn::recycle`]).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

fn main() -> ExitCode {
    // `RGBN_HUGE_PAGES=0`: no transparent-huge-page advice on image buffers (a measuring
    // switch: BENCHMARKS.md, "Huge pages").
    if std::env::var_os("RGBN_HUGE_PAGES").is_some_and(|v| v == "0") {
        rgbn::recycle::set_huge_pages(false);
    }
    init_logging();
    // A bad `RGBN_SIMD` (an unknown twin, or one this CPU cannot run) stops here, before any
    // work, rather than silently running another twin.
    if let Err(e) = rgbn::raster::simd::from_env() {
        eprintln!("rgbn: error: {e}");
        return ExitCode::from(2);
    }
    rgbn::cli::run(std::env::args_os()).into()
}

/// Warnings and errors logged by the library (e.g. "disk cache write failed") go to stderr as
/// `rgbn: warning: …` lines. `RUST_LOG` selects more (`RUST_LOG=debug`, `RUST_LOG=rgbn=info`);
/// the default is `warn` for rgbn and `error` for the libraries it uses. Diagnostics have their
/// own targets: `rgbn::editor::timing` (info: the editor's timings) and `rgbn::bini` (debug:
/// each reweighting step of bilateral integration); the older switches `RGBN_EDITOR_TIMING`
/// and `RGBN_BINI_TRACE` enable them too.
fn init_logging() {
    // Without RUST_LOG: rgbn's own warnings, and only errors from the libraries beneath it
    // (winit and eframe warn about things a user cannot act on, e.g. a virtual display's size).
    let mut directives = match std::env::var("RUST_LOG") {
        Ok(v) if !v.trim().is_empty() => v,
        _ => "error,rgbn=warn".to_string(),
    };
    for (var, directive) in [
        ("RGBN_EDITOR_TIMING", "rgbn::editor::timing=info"),
        ("RGBN_BINI_TRACE", "rgbn::bini=debug"),
    ] {
        if std::env::var_os(var).is_some() {
            directives.push(',');
            directives.push_str(directive);
        }
    }
    let filter = EnvFilter::builder()
        .with_default_directive(LevelFilter::WARN.into())
        .parse_lossy(directives);
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .event_format(OneLine)
        .try_init();
}

/// `rgbn: LEVEL: message`, the form of the CLI's own error lines.
struct OneLine;

impl<S, N> FormatEvent<S, N> for OneLine
where
    S: tracing::Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
{
    fn format_event(
        &self,
        ctx: &FmtContext<'_, S, N>,
        mut w: Writer<'_>,
        event: &tracing::Event<'_>,
    ) -> std::fmt::Result {
        let level = match *event.metadata().level() {
            tracing::Level::ERROR => "error",
            tracing::Level::WARN => "warning",
            tracing::Level::INFO => "info",
            tracing::Level::DEBUG => "debug",
            tracing::Level::TRACE => "trace",
        };
        write!(w, "rgbn: {level}: ")?;
        ctx.field_format().format_fields(w.by_ref(), event)?;
        writeln!(w)
    }
}
