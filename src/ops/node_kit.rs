//! Parameter pieces shared by several node wrappers: the border mode, a frequency band
//! ([`Band`]), a tangent frame ([`Frame`]) and the `relative_rms_curl` output that nonlinear
//! (and any other) editing nodes report.

use super::band::Band;
use super::params::{Meta, ParamVisitor};
use super::rotate::Frame;
use super::{PortSpec, PortType};
use crate::error::RgbnError;
use crate::raster::convolve::BorderMode;

/// Border mode names, in [`BorderMode::ALL`] order.
pub const BORDERS: [&str; 4] = ["mirror", "clamp", "wrap", "zero"];

/// Declares a `border` choice parameter.
pub fn visit_border(v: &mut dyn ParamVisitor, border: &mut &'static str) {
    v.choice(
        "border",
        border,
        &BORDERS,
        &Meta::new("How the image is extended beyond its border."),
    );
}

/// The border mode called `name` (the default for an unknown name, which the visitor refuses).
#[must_use]
pub fn border_mode(name: &str) -> BorderMode {
    BorderMode::ALL
        .into_iter()
        .find(|b| b.name() == name)
        .unwrap_or_default()
}

/// A [`Band`] as node parameters: a kind and its σ's.
#[derive(Clone, Debug, PartialEq)]
pub struct BandChoice {
    /// `lowpass`, `highpass`, `bandpass`, `log` (and `none` where allowed).
    pub band: &'static str,
    /// σ of the band; the finer σ of a band-pass.
    pub sigma_px: f64,
    /// Coarser σ of a band-pass.
    pub sigma_coarse_px: f64,
}

impl BandChoice {
    /// Band-pass 1–4 px.
    #[must_use]
    pub fn new(band: &'static str) -> Self {
        Self {
            band,
            sigma_px: 1.0,
            sigma_coarse_px: 4.0,
        }
    }

    /// Declares the three parameters; `options` lists the band names offered.
    pub fn visit(
        &mut self,
        v: &mut dyn ParamVisitor,
        name: &'static str,
        options: &[&'static str],
        doc: &'static str,
    ) {
        v.choice(name, &mut self.band, options, &Meta::new(doc));
        let sigma = |doc| Meta::new(doc).unit("px").range(0.05, 4096.0);
        v.float(
            "sigma_px",
            &mut self.sigma_px,
            &sigma("σ of the band (low-pass, high-pass, LoG), or the finer σ of a band-pass."),
        );
        v.float(
            "sigma_coarse_px",
            &mut self.sigma_coarse_px,
            &sigma("The coarser σ of a band-pass (must exceed sigma_px); unused by the others."),
        );
    }

    /// The band (`None` for `none`), checked; errors name this node's parameters.
    pub fn band(&self) -> Result<Option<Band>, RgbnError> {
        let (s, c) = (self.sigma_px as f32, self.sigma_coarse_px as f32);
        let band = match self.band {
            "lowpass" => Band::LowPass { sigma_px: s },
            "highpass" => Band::HighPass { sigma_px: s },
            "bandpass" => Band::BandPass {
                sigma_fine_px: s,
                sigma_coarse_px: c,
            },
            "log" => Band::LoG { sigma_px: s },
            _ => return Ok(None),
        };
        band.validate().map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } if name == "sigma_fine_px" => {
                RgbnError::param("sigma_px", detail)
            }
            other => other,
        })?;
        Ok(Some(band))
    }
}

/// Frame names.
pub const FRAMES: [&str; 2] = ["minimal", "oriented"];

/// A [`Frame`] as node parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameChoice {
    /// `minimal` or `oriented`.
    pub frame: &'static str,
    /// Orientation vector of the oriented frame.
    pub orientation: [f64; 3],
}

impl Default for FrameChoice {
    fn default() -> Self {
        Self {
            frame: "minimal",
            orientation: [1.0, 0.0, 0.0],
        }
    }
}

impl FrameChoice {
    /// Declares `frame` and `orientation`.
    pub fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.choice(
            "frame",
            &mut self.frame,
            &FRAMES,
            &Meta::new("Tangent frame of the base normal: minimal (shortest-arc rotation from +z; Blend = RNM) or oriented (tangent = orientation projected on the tangent plane)."),
        );
        v.vec3(
            "orientation",
            &mut self.orientation,
            &Meta::new(
                "Orientation vector of the oriented frame (x right, y up, z to the viewer).",
            )
            .range(-1e6, 1e6),
        );
    }

    /// The frame, checked.
    pub fn frame(&self) -> Result<Frame, RgbnError> {
        let f = match self.frame {
            "oriented" => Frame::Oriented {
                orientation: self.orientation.map(|x| x as f32),
            },
            _ => Frame::MinimalRotation,
        };
        f.validate()?;
        Ok(f)
    }
}

/// The `relative_rms_curl` output port.
#[must_use]
pub fn curl_port(what: &str) -> PortSpec {
    PortSpec {
        name: "relative_rms_curl".into(),
        ty: PortType::Number,
        doc: format!(
            "RMS(curl) / RMS(|g|) of the {what} inside the mask: the integrability readout (0 for the gradients of a height)."
        ),
        optional: false,
    }
}
