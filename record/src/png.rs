//! PNG files of the figures: RGB rasters written with the `png` crate (plotters draws into a buffer), and
//! read back (to check a figure, as the tests do). Pure Rust, no image library.

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::Path;

/// An 8-bit RGB raster, rows top to bottom.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Raster {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// `3 · width · height` bytes, R G B per pixel.
    pub rgb: Vec<u8>,
}

impl Raster {
    /// (width, height).
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The pixel at column `x`, row `y` (panics outside the raster).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Every pixel with its column and row, row by row.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32, [u8; 3])> + '_ {
        let w = self.width.max(1);
        self.rgb.chunks_exact(3).enumerate().map(move |(i, p)| (i as u32 % w, i as u32 / w, [p[0], p[1], p[2]]))
    }
}

/// Writes `rgb` (`3 · width · height` bytes) to `path` as an 8-bit RGB PNG.
pub(crate) fn write(path: &Path, (width, height): (u32, u32), rgb: &[u8]) -> Result<(), String> {
    let file = File::create(path).map_err(|e| e.to_string())?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

/// Reads the 8-bit RGB or RGBA PNG `path` (alpha dropped); errors name the file.
pub fn read(path: &Path) -> Result<Raster, String> {
    let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let file = File::open(path).map_err(|e| fail(&e))?;
    let mut reader = png::Decoder::new(BufReader::new(file)).read_info().map_err(|e| fail(&e))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).map_err(|e| fail(&e))?;
    let channels = match (info.color_type, info.bit_depth) {
        (png::ColorType::Rgb, png::BitDepth::Eight) => 3,
        (png::ColorType::Rgba, png::BitDepth::Eight) => 4,
        (c, d) => return Err(fail(&format!("not 8-bit RGB(A) but {c:?} {d:?}"))),
    };
    let rgb = buf[..info.buffer_size()].chunks_exact(channels).flat_map(|p| [p[0], p[1], p[2]]).collect();
    Ok(Raster { width: info.width, height: info.height, rgb })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_raster_round_trips_and_bad_files_are_errors() {
        let dir = std::env::temp_dir().join(format!("uavloc-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("r.png");
        let rgb: Vec<u8> = (0..3 * 5 * 4).map(|i| (i * 7 % 256) as u8).collect();
        write(&path, (5, 4), &rgb).unwrap();
        let r = read(&path).unwrap();
        assert_eq!((r.dimensions(), &r.rgb), ((5, 4), &rgb));
        assert_eq!(r.pixel(1, 2), [rgb[33], rgb[34], rgb[35]]);
        assert_eq!(r.pixels().nth(11).map(|(x, y, _)| (x, y)), Some((1, 2)));
        std::fs::write(&path, b"not a png").unwrap();
        assert!(read(&path).unwrap_err().contains("r.png"));
        assert!(read(&dir.join("missing.png")).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
