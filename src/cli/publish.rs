//! `rgbn publish`: the web viewer folder (a part of [`crate::cli`]; the writer is
//! [`crate::ops::publish`]).

use super::error::CliError;
use super::image::{parse_vec3, InputArgs};
use super::out::Out;
use crate::ops::params::Choice;
use crate::ops::publish::{publish, PublishOptions, WebView, MAX_LIGHTS};
use crate::render::{Light, Shading};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct PublishArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Initial light direction x,y,z towards the light (+x right, +y up, +z to the viewer).
    /// Repeat for several lights (at most 8); default -0.5,0.6,0.8.
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
    /// Initial exposure in stops.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,
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
