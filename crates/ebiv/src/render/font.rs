//! A small built-in bitmap font for axis labels, tick labels and colour bars, so figures need
//! no system fonts.
//!
//! Glyphs are at most 5 pixels wide on a 9-row cell: rows 0–6 hold capitals and digits
//! (baseline under row 6), rows 7–8 the descenders of g, j, p, q, y. Each glyph is written
//! as its rows separated by spaces, `#` for ink and `.` for paper; narrow glyphs (punctuation)
//! are narrower, which gives proportional spacing where it matters. Text is drawn with an
//! integer scale factor, each font pixel becoming a `scale × scale` block.

use image::RgbImage;

/// Rows of the glyph cell (cap height 7 plus 2 rows of descender).
pub const CELL_HEIGHT: u32 = 9;
/// Blank columns between glyphs.
const SPACING: u32 = 1;

/// The glyph table, drawn for this project.
const GLYPHS: &[(char, &str)] = &[
    ('0', ".###. #...# #..## #.#.# ##..# #...# .###."),
    ('1', "..#.. .##.. ..#.. ..#.. ..#.. ..#.. .###."),
    ('2', ".###. #...# ....# ...#. ..#.. .#... #####"),
    ('3', ".###. #...# ....# ..##. ....# #...# .###."),
    ('4', "...#. ..##. .#.#. #..#. ##### ...#. ...#."),
    ('5', "##### #.... ####. ....# ....# #...# .###."),
    ('6', "..##. .#... #.... ####. #...# #...# .###."),
    ('7', "##### ....# ...#. ..#.. .#... .#... .#..."),
    ('8', ".###. #...# #...# .###. #...# #...# .###."),
    ('9', ".###. #...# #...# .#### ....# ...#. .##.."),
    ('A', ".###. #...# #...# ##### #...# #...# #...#"),
    ('B', "####. #...# #...# ####. #...# #...# ####."),
    ('C', ".###. #...# #.... #.... #.... #...# .###."),
    ('D', "###.. #..#. #...# #...# #...# #..#. ###.."),
    ('E', "##### #.... #.... ####. #.... #.... #####"),
    ('F', "##### #.... #.... ####. #.... #.... #...."),
    ('G', ".###. #...# #.... #.### #...# #...# .####"),
    ('H', "#...# #...# #...# ##### #...# #...# #...#"),
    ('I', ".###. ..#.. ..#.. ..#.. ..#.. ..#.. .###."),
    ('J', "..### ...#. ...#. ...#. ...#. #..#. .##.."),
    ('K', "#...# #..#. #.#.. ##... #.#.. #..#. #...#"),
    ('L', "#.... #.... #.... #.... #.... #.... #####"),
    ('M', "#...# ##.## #.#.# #.#.# #...# #...# #...#"),
    ('N', "#...# #...# ##..# #.#.# #..## #...# #...#"),
    ('O', ".###. #...# #...# #...# #...# #...# .###."),
    ('P', "####. #...# #...# ####. #.... #.... #...."),
    ('Q', ".###. #...# #...# #...# #.#.# #..#. .##.#"),
    ('R', "####. #...# #...# ####. #.#.. #..#. #...#"),
    ('S', ".#### #.... #.... .###. ....# ....# ####."),
    ('T', "##### ..#.. ..#.. ..#.. ..#.. ..#.. ..#.."),
    ('U', "#...# #...# #...# #...# #...# #...# .###."),
    ('V', "#...# #...# #...# #...# #...# .#.#. ..#.."),
    ('W', "#...# #...# #...# #.#.# #.#.# #.#.# .#.#."),
    ('X', "#...# #...# .#.#. ..#.. .#.#. #...# #...#"),
    ('Y', "#...# #...# .#.#. ..#.. ..#.. ..#.. ..#.."),
    ('Z', "##### ....# ...#. ..#.. .#... #.... #####"),
    ('a', "..... ..... .###. ....# .#### #...# .####"),
    ('b', "#.... #.... ####. #...# #...# #...# ####."),
    ('c', "..... ..... .###. #.... #.... #...# .###."),
    ('d', "....# ....# .#### #...# #...# #...# .####"),
    ('e', "..... ..... .###. #...# ##### #.... .###."),
    ('f', "..##. .#..# .#... ###.. .#... .#... .#..."),
    ('g', "..... ..... .#### #...# #...# #...# .#### ....# .###."),
    ('h', "#.... #.... #.##. ##..# #...# #...# #...#"),
    ('i', "..#.. ..... .##.. ..#.. ..#.. ..#.. .###."),
    ('j', "...#. ..... ..##. ...#. ...#. ...#. ...#. #..#. .##.."),
    ('k', "#.... #.... #..#. #.#.. ##... #.#.. #..#."),
    ('l', ".##.. ..#.. ..#.. ..#.. ..#.. ..#.. .###."),
    ('m', "..... ..... ##.#. #.#.# #.#.# #.#.# #.#.#"),
    ('n', "..... ..... #.##. ##..# #...# #...# #...#"),
    ('o', "..... ..... .###. #...# #...# #...# .###."),
    ('p', "..... ..... ####. #...# #...# #...# ####. #.... #...."),
    ('q', "..... ..... .#### #...# #...# #...# .#### ....# ....#"),
    ('r', "..... ..... #.##. ##..# #.... #.... #...."),
    ('s', "..... ..... .#### #.... .###. ....# ####."),
    ('t', ".#... .#... ###.. .#... .#... .#..# ..##."),
    ('u', "..... ..... #...# #...# #...# #..## .##.#"),
    ('v', "..... ..... #...# #...# #...# .#.#. ..#.."),
    ('w', "..... ..... #...# #...# #.#.# #.#.# .#.#."),
    ('x', "..... ..... #...# .#.#. ..#.. .#.#. #...#"),
    ('y', "..... ..... #...# #...# #...# #...# .#### ....# .###."),
    ('z', "..... ..... ##### ...#. ..#.. .#... #####"),
    (' ', "... ... ... ... ... ... ..."),
    ('-', "..... ..... ..... ##### ..... ..... ....."),
    ('+', "..... ..#.. ..#.. ##### ..#.. ..#.. ....."),
    ('=', "..... ..... ##### ..... ##### ..... ....."),
    ('.', ". . . . . . #"),
    (',', ".. .. .. .. .. .# .# #."),
    (':', ". . # . . # ."),
    ('\'', "# # . . . . ."),
    ('/', "....# ....# ...#. ..#.. .#... #.... #...."),
    ('(', "..# .#. #.. #.. #.. .#. ..#"),
    (')', "#.. .#. ..# ..# ..# .#. #.."),
    ('[', "### #.. #.. #.. #.. #.. ###"),
    (']', "### ..# ..# ..# ..# ..# ###"),
    ('|', "# # # # # # # #"),
    ('_', "..... ..... ..... ..... ..... ..... ..... #####"),
    ('%', "##... ##..# ...#. ..#.. .#... #..## ...##"),
    ('<', "...#. ..#.. .#... #.... .#... ..#.. ...#."),
    ('>', ".#... ..#.. ...#. ....# ...#. ..#.. .#..."),
    ('?', ".###. #...# ....# ...#. ..#.. ..... ..#.."),
    ('·', ". . . # . . ."),
    ('×', "..... ..... #...# .#.#. ..#.. .#.#. #...#"),
    ('±', "..#.. ..#.. ##### ..#.. ..#.. ..... #####"),
    ('°', ".##. #..# .##. .... .... .... ...."),
    ('µ', "..... ..... #...# #...# #...# ##..# #.##. #.... #...."),
    ('τ', "..... ..... ##### ..#.. ..#.. ..#.. ...##"),
];

/// The art of `c`; unknown characters are drawn as `?`, the minus sign as `-`.
fn glyph(c: char) -> &'static str {
    let c = if c == '−' { '-' } else { c };
    GLYPHS
        .iter()
        .find(|(g, _)| *g == c)
        .or_else(|| GLYPHS.iter().find(|(g, _)| *g == '?'))
        .map(|(_, art)| *art)
        .unwrap_or("")
}

/// Width of a glyph in font pixels.
fn glyph_width(art: &str) -> u32 {
    art.split(' ')
        .next()
        .map_or(0, |row| row.chars().count() as u32)
}

/// Width in output pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    let n = text.chars().count() as u32;
    let ink: u32 = text.chars().map(|c| glyph_width(glyph(c))).sum();
    (ink + n.saturating_sub(1) * SPACING) * scale
}

/// Height in output pixels of one line of text at `scale`, descenders included.
pub fn text_height(scale: u32) -> u32 {
    CELL_HEIGHT * scale
}

/// Horizontal placement of text relative to the anchor point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Align {
    /// The anchor is the left edge of the text.
    Left,
    /// The anchor is the centre of the text.
    Centre,
    /// The anchor is the right edge of the text.
    Right,
}

/// Draw `text` with its top edge at `y` and horizontal placement `align` about `x`.
/// Pixels outside the image are skipped.
pub fn draw_text(
    img: &mut RgbImage,
    x: i64,
    y: i64,
    text: &str,
    scale: u32,
    colour: [u8; 3],
    align: Align,
) {
    let w = text_width(text, scale) as i64;
    let x0 = match align {
        Align::Left => x,
        Align::Centre => x - w / 2,
        Align::Right => x - w,
    };
    let s = scale.max(1) as i64;
    let mut pen = x0;
    for c in text.chars() {
        let art = glyph(c);
        for_each_ink(art, |col, row| {
            fill_block(img, pen + col * s, y + row * s, s, s, colour)
        });
        pen += (glyph_width(art) + SPACING) as i64 * s;
    }
}

/// Draw `text` rotated a quarter turn counter-clockwise (reading bottom to top), as a y-axis
/// label: its left edge is at `x`, and it is centred vertically on `y_centre`.
pub fn draw_text_vertical(
    img: &mut RgbImage,
    x: i64,
    y_centre: i64,
    text: &str,
    scale: u32,
    colour: [u8; 3],
) {
    let s = scale.max(1) as i64;
    let len = text_width(text, scale) as i64;
    // Text x runs up the image from the bottom; text row r maps to image column x + r.
    let bottom = y_centre + len / 2;
    let mut pen = 0i64;
    for c in text.chars() {
        let art = glyph(c);
        for_each_ink(art, |col, row| {
            fill_block(img, x + row * s, bottom - (pen + col + 1) * s, s, s, colour)
        });
        pen += (glyph_width(art) + SPACING) as i64;
    }
}

fn for_each_ink(art: &str, mut f: impl FnMut(i64, i64)) {
    for (row, bits) in art.split(' ').enumerate() {
        for (col, b) in bits.chars().enumerate() {
            if b == '#' {
                f(col as i64, row as i64);
            }
        }
    }
}

fn fill_block(img: &mut RgbImage, x: i64, y: i64, w: i64, h: i64, colour: [u8; 3]) {
    let (iw, ih) = (img.width() as i64, img.height() as i64);
    for yy in y.max(0)..(y + h).min(ih) {
        for xx in x.max(0)..(x + w).min(iw) {
            img.put_pixel(xx as u32, yy as u32, image::Rgb(colour));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glyph_table_is_well_formed() {
        for (c, art) in GLYPHS {
            let rows: Vec<&str> = art.split(' ').collect();
            assert!(rows.len() as u32 <= CELL_HEIGHT, "{c:?} too tall");
            let w = rows[0].chars().count();
            assert!((1..=5).contains(&w), "{c:?} width {w}");
            for r in &rows {
                assert_eq!(r.chars().count(), w, "{c:?} ragged");
                assert!(r.chars().all(|b| b == '#' || b == '.'), "{c:?} bad art");
            }
            let count = GLYPHS.iter().filter(|(g, _)| g == c).count();
            assert_eq!(count, 1, "{c:?} defined twice");
        }
        for c in ('a'..='z').chain('A'..='Z').chain('0'..='9') {
            assert!(GLYPHS.iter().any(|(g, _)| *g == c), "{c:?} missing");
        }
    }

    #[test]
    fn text_is_drawn_where_measured_and_clipped_at_edges() {
        let mut img = RgbImage::new(60, 20);
        draw_text(&mut img, 1, 1, "x [px]", 2, [255, 0, 0], Align::Left);
        let w = text_width("x [px]", 2);
        let inked: Vec<u32> = img
            .enumerate_pixels()
            .filter(|(_, _, p)| p.0 == [255, 0, 0])
            .map(|(x, _, _)| x)
            .collect();
        assert!(!inked.is_empty());
        assert!(*inked.iter().max().unwrap() < 1 + w);
        // Far outside or partly outside: no panic.
        draw_text(&mut img, -1000, -5, "-0.5e3 µs", 3, [0, 0, 0], Align::Right);
        draw_text_vertical(&mut img, 55, 10, "y [px] ?☃", 2, [0, 0, 255]);
    }
}
