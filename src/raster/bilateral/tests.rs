use super::*;

#[test]
fn every_twin_this_cpu_runs_equals_the_portable_one_within_2e_6() {
    // The AVX-512 / AVX2 twins use FMA, the portable one does not: equal to rounding
    // ([`TWIN_TOLERANCE`]). Every twin the CPU runs is compared, the narrower ones too (AVX2
    // on an AVX-512 machine). (The default one is checked against an f64 brute force in
    // `ops::bilateral`.)
    let (w, h) = (70, 40);
    let n = w * h;
    let f = |i: usize, a: f32, b: f32| ((i % w) as f32 * a + (i / w) as f32 * b).sin();
    let (mut nx, mut ny, mut nz) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for i in 0..n {
        let (p, q) = (0.8 * f(i, 0.31, 0.17), 0.8 * f(i, 0.13, 0.41));
        let l = (p * p + q * q + 1.0f32).sqrt();
        (nx[i], ny[i], nz[i]) = (-p / l, -q / l, 1.0 / l);
    }
    let c: Vec<Vec<f32>> = (0..3)
        .map(|k| {
            (0..n)
                .map(|i| 0.5 + 0.5 * f(i, 0.05 * (k + 1) as f32, 0.07))
                .collect()
        })
        .collect();
    let mask: Vec<f32> = (0..n).map(|i| if i % 7 == 3 { 0.2 } else { 1.0 }).collect();
    let input = Input {
        width: w,
        height: h,
        normal: [&nx, &ny, &nz],
        color: [&c[0], &c[1], &c[2]],
        mask: Some(&mask),
    };
    // The symmetric (pair) kernel, and the one-weight-per-tap kernel of wide discs (r = 34 >
    // SYM_MAX_RADIUS, sampled every 4 pixels).
    for (radius, stride) in [(4, 1), (34, 4)] {
        for (sn, metric) in [
            (Some(0.2), RangeMetric::Angle),
            (Some(0.6), RangeMetric::Angle),
            (Some(0.3), RangeMetric::OneMinusDot),
            (None, RangeMetric::Angle),
        ] {
            for sc in [Some(0.2), None] {
                let spec = Spec {
                    sigma_spatial: 2.0,
                    radius,
                    stride,
                    sigma_color: sc,
                    sigma_normal: sn,
                    metric,
                    filter_color: true,
                };
                let portable = filter_with(&input, &spec, Simd::Portable);
                for simd in Simd::supported_levels().filter(|&l| l != Simd::Portable) {
                    let o = filter_with(&input, &spec, simd);
                    let planes = o.normal.iter().chain(o.color.as_ref().unwrap());
                    let base = portable
                        .normal
                        .iter()
                        .chain(portable.color.as_ref().unwrap());
                    for (a, b) in planes.zip(base) {
                        let d = a
                            .iter()
                            .zip(b)
                            .map(|(x, y)| (x - y).abs())
                            .fold(0.0, f32::max);
                        assert!(
                            d <= TWIN_TOLERANCE,
                            "{simd} r {radius} {sn:?} {metric:?} {sc:?}: {d}"
                        );
                    }
                }
            }
        }
    }
}
