//! The fused Gaussian filter at image sizes where its planes are big blocks: with the
//! recycling allocator they are cache-line aligned, so the column sweep writes the normals with
//! non-temporal stores (on AVX-512 machines) and the parked planes are reused between calls.
//! The result must be, bit for bit, that of the unfused path, call after call.

use rgbn::ops::filter::{filter_normals, filter_normals_general, FilterOptions, Kernel};
use rgbn::raster::sample::Surface;

#[test]
fn fused_gaussian_on_big_planes_equals_the_unfused_path_bit_for_bit_call_after_call() {
    // 1024 × 1040: 4.3 MB planes (over the recycling threshold), 65 bands of rows;
    // then a width that is not a multiple of 16 (plain stores, a partial column group).
    for (w, h) in [(1024usize, 1040usize), (1030, 1024)] {
        let (img, _) = Surface::Sinusoid {
            amplitude_px: 2.0,
            period_px: 37.0,
        }
        .render(w, h);
        let opts = FilterOptions::default();
        for sigma in [8.0f32, 2.0] {
            let k = [Kernel::Gaussian { sigma_px: sigma }];
            let (want, _) = filter_normals_general(&img, &k, &opts).unwrap();
            // Three calls: fresh blocks, then kept ones (output planes and parked planes).
            for call in 0..3 {
                let (got, rep) = filter_normals(&img, &k, &opts).unwrap();
                for (c, (a, b)) in got.normal().iter().zip(want.normal()).enumerate() {
                    let differ = a
                        .iter()
                        .zip(b.iter())
                        .filter(|(x, y)| x.to_bits() != y.to_bits())
                        .count();
                    assert_eq!(differ, 0, "{w}×{h} σ {sigma} call {call}: plane {c}");
                }
                // The filter smoothed: curl and gradient shrink.
                assert!(rep.curl_after.rms_gradient < rep.curl_before.rms_gradient);
            }
        }
    }
}
