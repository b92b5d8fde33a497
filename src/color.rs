//! Colour: the [`Rgb`] triple every stage carries (radiance in W·sr⁻¹·m⁻², reflectance, or a
//! per-channel factor), Rec.709 luminance, and the radiance → display colour pipeline shared
//! by the writers and the rasteriser: the auto-exposure rule, the exact sRGB transfer
//! function and quantisation to 8 bits. An 8-bit channel is
//! `round(255 · srgb_encode(clamp(radiance · exposure, 0, 1)))`. It does not know about files
//! or formats ([`crate::io`]) or pictures ([`crate::render`]).

use crate::error::{Error, Result};

/// An RGB triple (radiance in W·sr⁻¹·m⁻², or a dimensionless per-channel factor such as ρ).
pub type Rgb = [f64; 3];

/// Linear value at which the sRGB curve switches from the linear toe to the power law
/// (IEC 61966-2-1).
pub const SRGB_LINEAR_LIMIT: f64 = 0.003_130_8;

/// The sRGB transfer function (IEC 61966-2-1) for linear `x` in [0, 1]:
/// `12.92 x` for `x ≤ 0.0031308`, else `1.055 x^(1/2.4) − 0.055`.
pub fn srgb_encode(x: f64) -> f64 {
    if x <= SRGB_LINEAR_LIMIT {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The inverse of [`srgb_encode`] for an encoded value `v` in [0, 1]: `v / 12.92` for
/// `v ≤ 0.04045`, else `((v + 0.055) / 1.055)^2.4` (IEC 61966-2-1).
pub fn srgb_decode(v: f64) -> f64 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// One linear channel value (already multiplied by the exposure) to an 8-bit sRGB code:
/// clamp to [0, 1] (NaN counts as 0), encode, scale by 255, round to nearest.
pub fn channel_to_srgb8(linear: f64) -> u8 {
    let x = if linear > 0.0 { linear.min(1.0) } else { 0.0 };
    (255.0 * srgb_encode(x)).round() as u8
}

/// Radiance (W·sr⁻¹·m⁻² per RGB channel) to an 8-bit sRGB colour at `exposure`.
pub fn radiance_to_srgb8(radiance: [f64; 3], exposure: f64) -> [u8; 3] {
    radiance.map(|c| channel_to_srgb8(c * exposure))
}

/// Rec.709 (= sRGB primaries) luminance of linear RGB: `0.2126 R + 0.7152 G + 0.0722 B`.
pub fn luminance(rgb: Rgb) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// Exposure: the factor radiance is multiplied by before the sRGB curve.
///
/// Rule: let Y = 0.2126 R + 0.7152 G + 0.0722 B (Rec.709 / sRGB luminance of the linear
/// radiance) for every vertex; over the vertices with Y > 0 take the 95th percentile of Y by
/// nearest rank (the value at 1-based rank ⌈0.95 n⌉ of the n values sorted ascending);
/// the exposure is 1 / that value. So at most the brightest 5 % of lit vertices (typically
/// the emitters) have luminance above 1 and saturate; unlit vertices do not count, so a large
/// shadowed area does not push the exposure up. If no vertex has Y > 0 the exposure is 1.
/// (Subnormal Y counts as 0, so the result is always finite.) Deterministic: it depends only
/// on the multiset of vertex radiances, not on their order or on threads.
///
/// Values whose luminance is not a normal positive number (0, subnormal, negative, NaN)
/// count as unlit, which keeps `1 / percentile` finite.
pub fn auto_exposure(vertex_radiance: &[[f64; 3]]) -> f64 {
    let mut lit: Vec<f64> = vertex_radiance
        .iter()
        .map(|&rgb| luminance(rgb))
        .filter(|&y| y >= f64::MIN_POSITIVE && y.is_finite())
        .collect();
    if lit.is_empty() {
        return 1.0;
    }
    lit.sort_unstable_by(f64::total_cmp);
    // Nearest rank: the smallest value with at least 95 % of the values at or below it,
    // 1-based rank ⌈0.95 n⌉, in integer arithmetic so no rounding can move it.
    let n = lit.len();
    let rank = (95 * n).div_ceil(100);
    1.0 / lit[rank - 1]
}

/// An exposure must be finite and > 0: an [`Error::Setting`] named `exposure` otherwise (the
/// writers, the rasteriser and [`crate::pipeline::WriteOptions`] check it the same way).
pub fn check_exposure(exposure: f64) -> Result<()> {
    if exposure > 0.0 && exposure.is_finite() {
        Ok(())
    } else {
        Err(Error::setting(
            "exposure",
            format!("{exposure} is not a finite number > 0"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_known_values() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-15);
        assert_eq!(channel_to_srgb8(0.0), 0);
        assert_eq!(channel_to_srgb8(1.0), 255);
        // 1.055 · 0.5^(1/2.4) − 0.055 = 0.735357; · 255 = 187.52 → 188.
        assert!((srgb_encode(0.5) - 0.735_356_983_052_449_5).abs() < 1e-12);
        assert_eq!(channel_to_srgb8(0.5), 188);
        // 18 % grey is the classic 118 (0.4613 · 255 = 117.6).
        assert_eq!(channel_to_srgb8(0.18), 118);
        // In the linear toe: 0.001 · 12.92 · 255 = 3.29 → 3.
        assert_eq!(channel_to_srgb8(0.001), 3);
    }

    #[test]
    fn srgb_decode_inverts_encode() {
        for i in 0..=1000 {
            let x = i as f64 / 1000.0;
            // The published constants meet to about 1e-8 at the toe (see below).
            assert!((srgb_decode(srgb_encode(x)) - x).abs() < 1e-7, "{x}");
        }
        // 8-bit 188 is linear 0.5029 (the code 0.5 rounds to).
        assert!((srgb_decode(188.0 / 255.0) - 0.502_886).abs() < 1e-6);
    }

    #[test]
    fn srgb_is_continuous_at_the_toe() {
        let below = srgb_encode(SRGB_LINEAR_LIMIT);
        let above = srgb_encode(SRGB_LINEAR_LIMIT * (1.0 + 1e-12));
        assert!((below - 12.92 * SRGB_LINEAR_LIMIT).abs() < 1e-18);
        // The two published constants meet to about 1e-8, not exactly.
        assert!((above - below).abs() < 1e-7, "{below} vs {above}");
    }

    #[test]
    fn quantisation_clamps_and_is_monotone_over_all_codes() {
        assert_eq!(channel_to_srgb8(-3.0), 0);
        assert_eq!(channel_to_srgb8(f64::NAN), 0);
        assert_eq!(channel_to_srgb8(7.5), 255);
        assert_eq!(channel_to_srgb8(f64::INFINITY), 255);
        let mut seen = [false; 256];
        let mut last = 0;
        let steps = 200_000;
        for i in 0..=steps {
            let k = channel_to_srgb8(i as f64 / steps as f64);
            assert!(k >= last);
            last = k;
            seen[k as usize] = true;
        }
        assert!(seen.iter().all(|&s| s), "every 8-bit code is reachable");
    }

    #[test]
    fn radiance_is_scaled_by_exposure_before_the_curve() {
        assert_eq!(radiance_to_srgb8([1.0, 2.0, 40.0], 0.25), [137, 188, 255]);
    }

    #[test]
    fn nearest_rank_percentile() {
        // One value: itself. Twenty values 1..=20: rank 19.
        let green = [0.0, 4.0 / 0.7152, 0.0];
        assert_eq!(auto_exposure(&[green]), 1.0 / luminance(green));
        assert!((auto_exposure(&[green]) - 0.25).abs() < 1e-15);
        let grey: Vec<[f64; 3]> = (1..=20).map(|k| [k as f64; 3]).collect();
        assert_eq!(auto_exposure(&grey), 1.0 / luminance([19.0; 3]));
        // 21 values: ⌈19.95⌉ = 20.
        let grey: Vec<[f64; 3]> = (1..=21).map(|k| [k as f64; 3]).collect();
        assert_eq!(auto_exposure(&grey), 1.0 / luminance([20.0; 3]));
        // Subnormal luminance counts as black.
        assert_eq!(auto_exposure(&[[1e-310, 0.0, 0.0]]), 1.0);
    }
}
