//! Compares two RGB EXR images of the same size: RMSE over all channels,
//! the mean of each channel, and non-finite pixels.
//!
//!     cargo run --release --example rmse -- image.exr reference.exr
//!
//! Used to compare glint's path tracer with Mitsuba 3's reference of the
//! Cornell box (`../shared/anchors/cornell/ref_512.exr`).

use exr::prelude::*;

fn load(path: &str) -> anyhow::Result<(usize, usize, Vec<[f32; 3]>)> {
    let image = read_first_rgba_layer_from_file(
        path,
        |res, _| {
            (
                res.width(),
                res.height(),
                vec![[0f32; 3]; res.width() * res.height()],
            )
        },
        |(w, _, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b];
        },
    )?;
    Ok(image.layer_data.channel_data.pixels)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [a, b] = &args[..] else {
        anyhow::bail!("usage: rmse IMAGE.exr REFERENCE.exr");
    };
    let (wa, ha, pa) = load(a)?;
    let (wb, hb, pb) = load(b)?;
    anyhow::ensure!(
        (wa, ha) == (wb, hb),
        "sizes differ: {wa}×{ha} and {wb}×{hb}"
    );
    let mut sq = 0.0f64;
    let mut mean = [[0.0f64; 3]; 2];
    let mut bad = 0;
    for (x, y) in pa.iter().zip(&pb) {
        if x.iter().any(|v| !v.is_finite()) {
            bad += 1;
            continue;
        }
        for c in 0..3 {
            sq += ((x[c] - y[c]) as f64).powi(2);
            mean[0][c] += x[c] as f64;
            mean[1][c] += y[c] as f64;
        }
    }
    let n = pa.len() as f64;
    println!(
        "rmse {:.5}  mean {:.5} {:.5} {:.5}  reference {:.5} {:.5} {:.5}  non-finite {bad}",
        (sq / (3.0 * n)).sqrt(),
        mean[0][0] / n,
        mean[0][1] / n,
        mean[0][2] / n,
        mean[1][0] / n,
        mean[1][1] / n,
        mean[1][2] / n,
    );
    Ok(())
}
