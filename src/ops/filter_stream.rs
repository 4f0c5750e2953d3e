//! Filters over an image read row by row ([`crate::raster::strips`]): each strip filtered in a
//! window grown by its halo, with the same kernel choice as [`super::filter_normals`].

use super::{filter_normals_general, fused, FilterOptions, FilterReport, Kernel};
use crate::error::RgbnError;
use crate::raster::convolve::{self, BorderMode, Fir, LineFilter};
use crate::raster::gradient::{curl_sums_of_normal_rows, CurlSums, NZ_EPSILON};
use crate::raster::smooth::smooth_normals;
use crate::raster::strips::{self, StreamInput, Window};
use crate::raster::Validation;

/// The rows of context a strip needs so that [`filter_streamed`] gives it what
/// [`filter_normals`](crate::ops::filter::filter_normals) gives the whole image: the kernels' supports added up, plus one row for
/// the curl readout's neighbour. `None` with the wrap border, which reads the opposite edge of
/// the image.
#[must_use]
pub fn stream_halo(kernels: &[Kernel], opts: &FilterOptions) -> Option<usize> {
    (opts.border != BorderMode::Wrap)
        .then(|| kernels.iter().map(Kernel::support_px).sum::<usize>() + 1)
}

/// [`filter_normals`](crate::ops::filter::filter_normals) over an image read row by row ([`crate::raster::strips`]): each strip is
/// filtered in a window grown by [`stream_halo`] rows (or `strip` rows when given; by default
/// [`strips::strip_rows`]), and `out` receives the window and the filtered normals of its core
/// rows, top to bottom. Returns the report, summed over the strips' core rows (`curl_after` is
/// read from the output normals; the whole-image path reads the filtered gradients before they
/// become normals: the same field up to rounding), and what was repaired in the input.
pub fn filter_streamed<E: From<RgbnError>>(
    input: &mut StreamInput,
    kernels: &[Kernel],
    opts: &FilterOptions,
    strip: Option<usize>,
    mut out: impl FnMut(&Window<'_>, [&[f32]; 3]) -> Result<(), E>,
) -> Result<(FilterReport, Validation), E> {
    for k in kernels {
        k.validate()?;
    }
    let halo = stream_halo(kernels, opts).ok_or_else(|| {
        RgbnError::param(
            "border",
            "the wrap border reads the opposite edge of the image, so it cannot be streamed",
        )
    })?;
    let w = input.size().0;
    let strip = strip.unwrap_or_else(|| strips::strip_rows(w, halo));
    let masked = opts.mask_aware && input.has_mask();
    let (mut clamped, mut before, mut after) = (0, CurlSums::default(), CurlSums::default());
    let repaired = strips::for_each_strip(input, halo, strip, |win| {
        // The same kernel choice as `filter_normals`.
        let filtered: [Vec<f32>; 3] = match kernels {
            [Kernel::Gaussian { sigma_px }] if !masked && *sigma_px < convolve::IIR_MIN_SIGMA => {
                smooth_window(win, &Fir::gaussian(*sigma_px), opts.border)
            }
            [Kernel::Gaussian { sigma_px }] if !masked => {
                smooth_window(win, &convolve::Deriche::new(*sigma_px), opts.border)
            }
            [Kernel::Box { radius_px }] if !masked => {
                let radius = *radius_px as usize;
                smooth_window(win, &convolve::BoxFilter { radius }, opts.border)
            }
            _ => {
                let img = win.image()?;
                let fused = match kernels {
                    [k] if !masked => fused::combination(&img, k, opts.border),
                    _ => None,
                };
                if let Some((normal, _, _)) = fused {
                    normal
                } else {
                    let (f, _) = filter_normals_general(&img, kernels, opts)?;
                    let [x, y, z] = f.normal();
                    [x.clone(), y.clone(), z.clone()]
                }
            }
        };
        let core = win.core.clone();
        let nz = win.core_of(win.normal[2]);
        clamped += nz.iter().filter(|&&z| z < NZ_EPSILON).count();
        before = before.merge(curl_sums_of_normal_rows(
            win.normal,
            win.mask,
            w,
            core.clone(),
        ));
        let [fx, fy, fz] = &filtered;
        let f3 = [&fx[..], &fy[..], &fz[..]];
        after = after.merge(curl_sums_of_normal_rows(f3, win.mask, w, core));
        out(win, f3.map(|p| win.core_of(p)))
    })?;
    Ok((
        FilterReport {
            clamped,
            curl_before: before.stats(),
            curl_after: after.stats(),
        },
        repaired,
    ))
}

/// [`smooth_normals`] of a strip's window.
fn smooth_window<F: LineFilter>(win: &Window<'_>, f: &F, border: BorderMode) -> [Vec<f32>; 3] {
    smooth_normals(win.normal, win.mask, win.width, win.rows(), f, border).normal
}
