//! `rgbn publish`: the web viewer folder (a part of [`crate::cli`]; the writer is
//! [`crate::ops::publish`]).

use super::error::CliError;
use super::image::{InputArgs, ShadingArgs};
use super::out::Out;
use crate::ops::publish::{publish, PublishOptions, WebView, MAX_LIGHTS};
use crate::params::Choice;
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
    /// with other files). Open its index.html in a browser (from disk or any web server).
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
    let (img, _) = a.input.load()?;
    let opts = PublishOptions {
        shading,
        view: a.view,
    };
    super::interrupt::check()?;
    let p = publish(&img, &a.output, &opts, &a.input.paths())?;
    let tiles: usize = p.levels.iter().map(|l| l.cols * l.rows).sum();
    out.line(format_args!(
        "published {}×{} ({} level{}, {} tile{}, curvature scale {:.4}/px): {}",
        img.width(),
        img.height(),
        p.levels.len(),
        if p.levels.len() == 1 { "" } else { "s" },
        tiles,
        if tiles == 1 { "" } else { "s" },
        p.curvature_scale,
        a.output.join("index.html").display()
    ))?;
    Ok(())
}
