//! `rgbn publish`: the web viewer folder (a part of [`crate::cli`]; the writer is
//! [`crate::ops::publish`]).

use super::error::CliError;
use super::image::{InputArgs, ShadingArgs};
use super::out::Out;
use crate::ops::publish::{
    publish, publish_stream, PublishOptions, Published, WebView, MAX_LIGHTS,
};
use crate::params::Choice;
use crate::raster::strips::{Opened, StreamInput};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct PublishArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// The page's initial shading (at most 8 lights).
    #[command(flatten)]
    pub shading: ShadingArgs,
    /// The view the page opens with: relit, normals, specular_enhancement, curvature.
    #[arg(long, default_value = "relit", value_parser = parse_web_view)]
    pub view: WebView,
    /// Output folder: created, or replaced when it holds an earlier publish (never a folder
    /// with other files). Show it with `rgbn serve DIR` (every level), or open its index.html
    /// from disk (up to 2048 px); docs/publishing.md: OpenSeadragon, OpenLIME.
    #[arg(short, long)]
    pub output: PathBuf,
}

fn parse_web_view(s: &str) -> Result<WebView, String> {
    WebView::ALL
        .iter()
        .copied()
        .find(|v| v.name() == s)
        .ok_or_else(|| {
            let names: Vec<&str> = WebView::ALL.iter().map(|v| v.name()).collect();
            format!("unknown view {s:?} ({})", names.join(", "))
        })
}

pub(super) fn publish_cmd(a: &PublishArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let shading = a.shading.shading()?;
    if shading.lights.len() > MAX_LIGHTS {
        return Err(super::error::usage(format!(
            "at most {MAX_LIGHTS} --light for the web viewer, got {}",
            shading.lights.len()
        )));
    }
    let opts = PublishOptions {
        shading,
        view: a.view,
    };
    let inputs = a.input.paths();
    // Read in strips whenever the files allow (PNG, TIFF in strips, scan-line EXR): memory is
    // then bounded by the strip, not the image; else whole.
    let streamed = if a.input.demo {
        None
    } else {
        match StreamInput::open(&a.input.spec(), &a.input.load_options())? {
            Opened::Stream(input) => Some(input),
            Opened::Whole(_) => None,
        }
    };
    let (p, how) = match streamed {
        Some(mut input) => {
            let (p, repaired) =
                publish_stream(&mut input, &a.output, &opts, &inputs, None, || {
                    super::interrupt::check()
                })?;
            super::image::note_repairs(&repaired, &a.input.spec().normal.or(a.input.file.clone()));
            (p, ", streamed")
        }
        None => {
            let (img, _) = a.input.load()?;
            super::interrupt::check()?;
            (publish(&img, &a.output, &opts, &inputs)?, "")
        }
    };
    summary(&p, how, a, out)
}

fn summary(p: &Published, how: &str, a: &PublishArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    out.line(format_args!(
        "published {}×{} ({} Deep Zoom levels, {} tile files, {:.1} MB{how}, curvature scale {:.4}/px): {} (rgbn serve {} shows every level)",
        p.size.0,
        p.size.1,
        p.levels.len(),
        p.tiles.tiles,
        p.bytes as f64 / 1e6,
        p.curvature_scale,
        a.output.join("index.html").display(),
        a.output.display()
    ))?;
    Ok(())
}
