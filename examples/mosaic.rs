//! Lays out the PNG crops of an N×M tile grid (from `glint render --tiles
//! NxM --tile-index K -o tK.png`) with gaps between them, to show how a
//! frame was split: `cargo run --example mosaic -- 4 4 GAP OUT.png t0.png …`.
//! (The README's picture of a tiled render is made this way.)

use image::{Rgb, RgbImage};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [columns, rows, gap, out, tiles @ ..] = &args[..] else {
        return Err("usage: mosaic COLUMNS ROWS GAP OUT.png TILE.png…".into());
    };
    let (columns, rows, gap): (u32, u32, u32) = (columns.parse()?, rows.parse()?, gap.parse()?);
    if tiles.len() as u32 != columns * rows {
        return Err(format!("expected {} tiles, got {}", columns * rows, tiles.len()).into());
    }
    let images: Vec<RgbImage> = tiles
        .iter()
        .map(|t| image::open(t).map(|i| i.to_rgb8()))
        .collect::<Result<_, _>>()?;
    let tile = |i: u32, j: u32| &images[(j * columns + i) as usize];
    let width: u32 = (0..columns).map(|i| tile(i, 0).width()).sum::<u32>() + gap * (columns + 1);
    let height: u32 = (0..rows).map(|j| tile(0, j).height()).sum::<u32>() + gap * (rows + 1);
    let mut canvas = RgbImage::from_pixel(width, height, Rgb([255, 255, 255]));
    let mut y = gap;
    for j in 0..rows {
        let mut x = gap;
        for i in 0..columns {
            image::imageops::replace(&mut canvas, tile(i, j), x as i64, y as i64);
            x += tile(i, j).width() + gap;
        }
        y += tile(0, j).height() + gap;
    }
    canvas.save(out)?;
    Ok(())
}
