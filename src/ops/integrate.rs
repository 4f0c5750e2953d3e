//! Parameters of the integration and mesh nodes ([`crate::nodes::integrate`]); the solvers
//! are [`crate::raster::integrate`] and [`crate::raster::mesh`].

use super::params::Choice;
use crate::error::RgbnError;
use crate::raster::integrate::{Differences, IntegrateParams, IntegrationMethod};
use crate::raster::mesh::{MeshFormat, MeshParams};

impl Choice for IntegrationMethod {
    const ALL: &'static [Self] = &[
        IntegrationMethod::PoissonDct,
        IntegrationMethod::FrankotChellappa,
        IntegrationMethod::MaskedPoisson,
    ];
    fn name(self) -> &'static str {
        match self {
            IntegrationMethod::PoissonDct => "poisson_dct",
            IntegrationMethod::FrankotChellappa => "frankot_chellappa",
            IntegrationMethod::MaskedPoisson => "masked_poisson",
        }
    }
    fn doc(self) -> &'static str {
        match self {
            IntegrationMethod::PoissonDct => {
                "Least squares, Neumann borders, DCT solver (mask ignored)."
            }
            IntegrationMethod::FrankotChellappa => "Periodic borders, FFT (mask ignored).",
            IntegrationMethod::MaskedPoisson => {
                "Only edges inside the image's mask, conjugate gradients."
            }
        }
    }
}

impl Choice for Differences {
    const ALL: &'static [Self] = &[Differences::Averaged, Differences::Forward];
    fn name(self) -> &'static str {
        match self {
            Differences::Averaged => "averaged",
            Differences::Forward => "forward",
        }
    }
    fn doc(self) -> &'static str {
        match self {
            Differences::Averaged => {
                "Edge slope = average of the two pixel samples: heights at pixel centres."
            }
            Differences::Forward => {
                "Edge slope = one pixel's sample (forward differences): half a pixel staggered for centre-sampled normals."
            }
        }
    }
}

impl Choice for MeshFormat {
    const ALL: &'static [Self] = &[MeshFormat::PlyBinary, MeshFormat::PlyAscii, MeshFormat::Obj];
    fn name(self) -> &'static str {
        match self {
            MeshFormat::PlyBinary => "ply",
            MeshFormat::PlyAscii => "ply_ascii",
            MeshFormat::Obj => "obj",
        }
    }
    fn doc(self) -> &'static str {
        match self {
            MeshFormat::PlyBinary => "PLY, binary little-endian.",
            MeshFormat::PlyAscii => "PLY, ASCII.",
            MeshFormat::Obj => "Wavefront OBJ (v x y z r g b, vn, f).",
        }
    }
}

crate::params! {
    /// Parameters of the integrate and project nodes (the graph form of [`IntegrateParams`]).
    #[derive(Clone, Debug, PartialEq)]
    pub struct IntegrateSettings {
        /// poisson_dct: least squares, Neumann borders, DCT solver (mask ignored); frankot_chellappa: periodic borders, FFT; masked_poisson: only edges inside the image's mask, conjugate gradients.
        pub method: IntegrationMethod = IntegrationMethod::PoissonDct => choice,
        /// Conjugate-gradient iteration cap (masked_poisson only).
        pub max_iterations: i64 = i64::from(IntegrateParams::default().max_iterations)
            => int.range(1.0, 1e7),
        /// Stop when ‖b − Lz‖ ≤ tolerance·‖b‖ (masked_poisson only).
        pub tolerance: f64 = IntegrateParams::default().tolerance => float.range(1e-12, 0.5),
        /// averaged: an edge's slope is the average of its two pixel samples (normals sampled at pixel centres; heights registered at pixel centres); forward: one pixel's sample per edge (exact for forward differences of a height; half a pixel staggered otherwise). Graphs that do not name it get averaged.
        pub differences: Differences = Differences::Averaged => choice,
    }
}

impl IntegrateSettings {
    /// The solver parameters, checked.
    pub fn params(&self) -> Result<IntegrateParams, RgbnError> {
        let p = IntegrateParams {
            method: self.method,
            max_iterations: u32::try_from(self.max_iterations)
                .map_err(|_| RgbnError::param("max_iterations", "out of range"))?,
            tolerance: self.tolerance,
            differences: self.differences,
        };
        p.validate()?;
        Ok(p)
    }
}

crate::params! {
    /// Parameters of the mesh-writing node.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SaveMeshSettings {
        /// Output mesh (.ply or .obj).
        pub path: String = String::new() => path.output(),
        /// ply (binary little-endian), ply_ascii, or obj (v x y z r g b, vn, f).
        pub format: MeshFormat = MeshFormat::PlyBinary => choice,
        /// Multiplies the height (relief exaggeration; not 0).
        pub z_scale: f64 = 1.0 => float.range(-1e6, 1e6),
        /// World size of one pixel.
        pub pixel_size: f64 = 1.0 => float.range(1e-9, 1e9),
    }
}

impl SaveMeshSettings {
    /// The mesh parameters, checked.
    pub fn params(&self) -> Result<MeshParams, RgbnError> {
        let p = MeshParams {
            format: self.format,
            z_scale: self.z_scale as f32,
            pixel_size: self.pixel_size as f32,
        };
        p.validate()?;
        Ok(p)
    }
}

crate::params! {
    /// Parameters of writing a height (any scalar field) to EXR.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SaveHeightParams {
        /// Output .exr (one f32 channel Y).
        pub path: String = String::new() => path.output(),
    }
}
