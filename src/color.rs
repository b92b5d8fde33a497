//! Colour: the [`Rgb`] triple every stage carries (radiance in W·sr⁻¹·m⁻², reflectance, or a
//! per-channel factor), Rec.709 luminance, and the radiance → display colour pipeline shared
//! by the writers and the rasteriser: the auto-exposure rule (a photographic key from the
//! area-weighted log-average luminance, [`auto_exposure`]), the exact sRGB transfer
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

/// The display value the log-average luminance maps to in [`auto_exposure`]: a fraction of
/// the display's white (dimensionless), photography's middle grey.
pub const KEY: f64 = 0.18;

/// The largest share of the lit area [`auto_exposure`] lets clip (some channel above the
/// display's white), dimensionless.
pub const CLIP_SHARE: f64 = 0.02;

/// Luminance below this fraction of the brightest counts as unlit in [`auto_exposure`]
/// (dimensionless): Reinhard's small δ that keeps black out of the logarithm.
pub const UNLIT: f64 = 1e-6;

/// Exposure: the factor radiance (W·sr⁻¹·m⁻²) is multiplied by before the sRGB curve, in
/// sr·m²·W⁻¹, from the key of the scene as photographic tone mapping takes it (Reinhard,
/// Stark, Shirley & Ferwerda 2002, "Photographic tone reproduction for digital images",
/// SIGGRAPH, equations 1 and 2).
///
/// Samples are `radiance[i]` with weight `area[i]` (the area each stands for, any unit; all
/// weights are taken as 1 if they sum to 0). Let Y = 0.2126 R + 0.7152 G + 0.0722 B (Rec.709
/// luminance). Samples with Y below [`UNLIT`] × the largest Y, or not finite, are unlit: they
/// show black at any exposure and are left out (the backs of a two-sided bake, surfaces no
/// light reaches). Over the lit samples:
///
/// 1. the log-average luminance L̄ = exp(Σ wᵢ ln Yᵢ / Σ wᵢ), and the exposure k = a / L̄ with
///    the key a = [`KEY`]: the scene's typical luminance maps to middle grey (a uniform scene
///    of luminance L gets k = a / L);
/// 2. then at most [`CLIP_SHARE`] of the lit weight may clip: with m the largest channel of a
///    sample and m* the smallest value such that the samples with m > m* weigh at most that
///    share, k = min(k, 1 / m*).
///
/// A few very bright samples (the emitters, sunlit patches) barely move L̄, so the rest of the
/// scene is not darkened to make room for them; the clamp keeps a scene that is mostly bright
/// from washing out. If no sample is lit the exposure is 1. The result is finite and > 0, and
/// depends only on the samples (not on threads).
pub fn auto_exposure(radiance: &[Rgb], area: &[f64]) -> f64 {
    let y_max = radiance
        .iter()
        .map(|&rgb| luminance(rgb))
        .filter(|y| y.is_finite())
        .fold(0.0, f64::max);
    if y_max < f64::MIN_POSITIVE {
        return 1.0;
    }
    let floor = (UNLIT * y_max).max(f64::MIN_POSITIVE);
    let weights_count = area.iter().any(|&w| w > 0.0 && w.is_finite());
    // (luminance, largest channel, weight) of the lit samples.
    let mut lit: Vec<(f64, f64, f64)> = radiance
        .iter()
        .zip(area.iter().copied().chain(std::iter::repeat(0.0)))
        .filter_map(|(&rgb, w)| {
            let y = luminance(rgb);
            let w = if weights_count { w } else { 1.0 };
            let m = rgb.into_iter().fold(0.0, f64::max);
            (y >= floor && y.is_finite() && w > 0.0 && w.is_finite() && m.is_finite())
                .then_some((y, m, w))
        })
        .collect();
    let total: f64 = lit.iter().map(|s| s.2).sum();
    if lit.is_empty() || total <= 0.0 || !total.is_finite() {
        return 1.0;
    }
    let log_mean = lit.iter().map(|&(y, _, w)| w * y.ln()).sum::<f64>() / total;
    let mut exposure = KEY / log_mean.exp();
    // The brightest samples first: those within the clip share may clip, the next may not.
    lit.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
    let mut clipped = 0.0;
    for &(_, m, w) in &lit {
        clipped += w;
        if clipped > CLIP_SHARE * total {
            exposure = exposure.min(1.0 / m);
            break;
        }
    }
    if exposure.is_finite() && exposure > 0.0 {
        exposure
    } else {
        1.0
    }
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
    fn uniform_scene_of_radiance_l_gets_the_key_over_l() {
        for l in [1e-6, 0.02, 1.0, 350.0] {
            let e = auto_exposure(&[[l; 3]; 7], &[0.5, 1.0, 2.0, 0.1, 3.0, 1.0, 1.0]);
            assert!((e * l / KEY - 1.0).abs() < 1e-12, "{l}: {e}");
        }
        // Coloured: by luminance.
        let green = [0.0, 4.0, 0.0];
        let e = auto_exposure(&[green], &[1.0]);
        assert!((e - KEY / (0.7152 * 4.0)).abs() < 1e-15);
    }

    #[test]
    fn a_few_bright_samples_do_not_darken_the_rest() {
        // 98 % of the area dim (0.01 to 0.03, mean 0.02), 2 % a thousand times brighter.
        let mut radiance = Vec::new();
        let mut area = Vec::new();
        for k in 0..98 {
            radiance.push([0.01 + 0.02 * (k % 3) as f64 / 2.0; 3]);
            area.push(1.0);
        }
        radiance.extend([[20.0; 3]; 2]);
        area.extend([1.0; 2]);
        let e = auto_exposure(&radiance, &area);
        // The dim part's mean maps near the key (the bright 2 % lift the log-average by
        // 1000^0.02 ≈ 1.15), not near black.
        let shown = 0.02 * e;
        assert!(shown > 0.12 && shown < KEY, "{shown}");
        // The 95th percentile rule this replaced put 20 at white: the dim part at 0.001.
        assert!(shown > 100.0 * 0.02 / 20.0);
        // The bright 2 % clip, the rest does not.
        assert!(20.0 * e > 1.0 && 0.03 * e < 1.0);
    }

    #[test]
    fn at_most_the_clip_share_of_the_area_clips() {
        // Half the area at 1, half at 100: the log-average 10 would put 100 at 1.8 (clipping
        // half the area); the clamp puts the brighter half at white.
        let e = auto_exposure(&[[1.0; 3], [100.0; 3]], &[1.0, 1.0]);
        assert!((e - 0.01).abs() < 1e-15, "{e}");
        // By area: a bright sample of 1 % of the area may clip.
        let e = auto_exposure(&[[1.0; 3], [100.0; 3]], &[99.0, 1.0]);
        assert!((e * 100.0f64.powf(0.01) - KEY).abs() < 1e-12, "{e}");
        // Clipping is per channel: a saturated blue (key alone: 50 · 0.18 / (0.0722 · 50) =
        // 2.5) counts by its blue.
        let e = auto_exposure(&[[0.0, 0.0, 50.0]], &[1.0]);
        assert!((e - 1.0 / 50.0).abs() < 1e-15, "{e}");
    }

    #[test]
    fn unlit_samples_and_weights_are_left_out() {
        // Black and subnormal samples do not count; no lit sample gives 1.
        assert_eq!(auto_exposure(&[[1e-310, 0.0, 0.0]], &[1.0]), 1.0);
        assert_eq!(auto_exposure(&[[0.0; 3]; 3], &[1.0; 3]), 1.0);
        assert_eq!(auto_exposure(&[], &[]), 1.0);
        let with_black = auto_exposure(&[[0.5; 3], [0.0; 3], [1e-12; 3]], &[1.0, 5.0, 5.0]);
        assert!((with_black - KEY / 0.5).abs() < 1e-15);
        // Zero weights everywhere count each sample once.
        let e = auto_exposure(&[[0.5; 3], [2.0; 3]], &[0.0, 0.0]);
        assert!((e - KEY).abs() < 1e-12, "{e}");
    }
}
