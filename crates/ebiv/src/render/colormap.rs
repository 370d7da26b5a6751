//! Colour maps.

/// The colour of an event at relative time `s` ∈ [−1, 1] (−1 oldest, 0 the reference time,
/// +1 newest): blue for the past, white for the present, red for the future, as in the
/// time-coded event images of Willert & Klinner (2022), Fig. 4.
pub fn time_code(s: f32) -> [u8; 3] {
    let s = s.clamp(-1.0, 1.0);
    let fade = |a: f32| (255.0 * (1.0 - a.abs())).round() as u8;
    if s < 0.0 {
        // white → blue: keep blue, lose red and green.
        [fade(s), fade(s * 0.6).max(64.min(fade(s))), 255]
    } else {
        [255, fade(s * 0.8).max(40.min(fade(s))), fade(s)]
    }
}

/// Key points of matplotlib's "inferno" colour map (perceptually uniform, dark to bright).
const INFERNO: [[u8; 3]; 9] = [
    [0, 0, 4],
    [31, 12, 72],
    [85, 15, 109],
    [136, 34, 106],
    [186, 54, 85],
    [227, 89, 51],
    [249, 140, 10],
    [249, 201, 50],
    [252, 255, 164],
];

/// Inferno colour at `s` ∈ [0, 1], linearly interpolated between key points.
pub fn inferno(s: f32) -> [u8; 3] {
    let s = if s.is_finite() {
        s.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let pos = s * (INFERNO.len() - 1) as f32;
    let i = (pos.floor() as usize).min(INFERNO.len() - 2);
    let f = pos - i as f32;
    let (a, b) = (INFERNO[i], INFERNO[i + 1]);
    std::array::from_fn(|k| (a[k] as f32 + f * (b[k] as f32 - a[k] as f32)).round() as u8)
}

/// Key points of ColorBrewer's diverging "RdBu" scheme, 11 classes (Brewer, colorbrewer2.org),
/// from blue to red: white in the middle, for signed quantities centred on 0.
const BLUE_RED: [[u8; 3]; 11] = [
    [5, 48, 97],
    [33, 102, 172],
    [67, 147, 195],
    [146, 197, 222],
    [209, 229, 240],
    [247, 247, 247],
    [253, 219, 199],
    [244, 165, 130],
    [214, 96, 77],
    [178, 24, 43],
    [103, 0, 31],
];

/// Diverging colour at `s` ∈ [0, 1]: blue below 0.5, white at 0.5, red above, linearly
/// interpolated between the key points of ColorBrewer's RdBu.
pub fn blue_red(s: f32) -> [u8; 3] {
    let s = if s.is_finite() {
        s.clamp(0.0, 1.0)
    } else {
        0.5
    };
    let pos = s * (BLUE_RED.len() - 1) as f32;
    let i = (pos.floor() as usize).min(BLUE_RED.len() - 2);
    let f = pos - i as f32;
    let (a, b) = (BLUE_RED[i], BLUE_RED[i + 1]);
    std::array::from_fn(|k| (a[k] as f32 + f * (b[k] as f32 - a[k] as f32)).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_code_endpoints() {
        assert_eq!(time_code(0.0), [255, 255, 255]);
        let past = time_code(-1.0);
        let future = time_code(1.0);
        assert!(past[2] == 255 && past[0] == 0, "past is blue: {past:?}");
        assert!(
            future[0] == 255 && future[2] == 0,
            "future is red: {future:?}"
        );
    }

    #[test]
    fn blue_red_is_white_in_the_middle_and_symmetric_in_lightness() {
        assert_eq!(blue_red(0.5), [247, 247, 247]);
        assert!(blue_red(0.0)[2] > blue_red(0.0)[0], "negative is blue");
        assert!(blue_red(1.0)[0] > blue_red(1.0)[2], "positive is red");
        assert_eq!(blue_red(f32::NAN), blue_red(0.5));
    }

    #[test]
    fn inferno_is_monotonic_in_brightness() {
        let lum = |c: [u8; 3]| c.iter().map(|&v| v as u32).sum::<u32>();
        let mut prev = 0;
        for i in 0..=20 {
            let l = lum(inferno(i as f32 / 20.0));
            assert!(l >= prev);
            prev = l;
        }
    }
}
