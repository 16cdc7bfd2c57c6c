//! The image being accumulated: per-pixel sums of radiance samples and of their squares
//! (for a per-pixel variance estimate) and the number of samples taken, for the whole image
//! or for a [`Region`] of it (`render --region`, one part of a render split across machines).

use crate::Rgb;
use serde::Serialize;

/// Edge length in pixels of the square tiles of one grid over the whole image: the render
/// loop's unit of work ([`crate::render`]) and the rows that [`Region::band`] shares out.
pub const TILE_SIZE: u32 = 16;

/// A rectangle of pixels [x0, x1) × [y0, y1) of an image, in pixels from the top-left
/// corner (ends exclusive).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct Region {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Region {
    /// All of a `width` × `height` image.
    pub fn whole(width: u32, height: u32) -> Self {
        Region { x0: 0, y0: 0, x1: width, y1: height }
    }

    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    pub fn pixel_count(&self) -> usize {
        self.width() as usize * self.height() as usize
    }

    /// True when the region holds at least one pixel and lies inside a `width` × `height`
    /// image.
    pub fn is_within(&self, width: u32, height: u32) -> bool {
        self.x0 < self.x1 && self.y0 < self.y1 && self.x1 <= width && self.y1 <= height
    }

    /// True when the two regions share a pixel.
    pub fn overlaps(&self, other: &Region) -> bool {
        self.x0 < other.x1 && other.x0 < self.x1 && self.y0 < other.y1 && other.y0 < self.y1
    }

    /// Band `k` (1-based) of `n` horizontal bands of a `width` × `height` image: whole rows of
    /// [`TILE_SIZE`]-pixel tiles shared out as evenly as they go (`render --tile K/N`).
    /// `None` when `k` is not in 1..=n or there are fewer tile rows than bands.
    pub fn band(width: u32, height: u32, k: u32, n: u32) -> Option<Region> {
        let rows = height.div_ceil(TILE_SIZE) as u64;
        if k == 0 || k > n || n as u64 > rows || width == 0 {
            return None;
        }
        let row = |i: u32| ((i as u64 * rows / n as u64) as u32 * TILE_SIZE).min(height);
        Some(Region { x0: 0, y0: row(k - 1), x1: width, y1: row(k) })
    }
}

impl std::fmt::Display for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.y0, self.x1, self.y1)
    }
}

impl std::str::FromStr for Region {
    type Err = String;

    /// Parses `X0,Y0,X1,Y1` (ends exclusive, X0 < X1, Y0 < Y1).
    fn from_str(s: &str) -> Result<Self, String> {
        let err = || format!("'{s}' is not X0,Y0,X1,Y1 (pixel bounds, ends exclusive, X0 < X1 and Y0 < Y1)");
        let v: Vec<u32> = s.split(',').map(|t| t.trim().parse::<u32>()).collect::<Result<_, _>>().map_err(|_| err())?;
        match v[..] {
            [x0, y0, x1, y1] if x0 < x1 && y0 < y1 => Ok(Region { x0, y0, x1, y1 }),
            _ => Err(err()),
        }
    }
}

/// Accumulated samples of an image or of a region of it, row-major from the region's
/// top-left pixel.
#[derive(Clone, Debug)]
pub struct Film {
    /// Size of the pixels held: the region's.
    pub width: u32,
    pub height: u32,
    /// Size of the whole image.
    pub full_width: u32,
    pub full_height: u32,
    /// Where the pixels held lie in the whole image.
    pub region: Region,
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    count: Vec<u32>,
}

/// The samples one pixel received in one pass.
#[derive(Clone, Copy, Debug, Default)]
pub struct PixelAccumulator {
    pub sum: [f64; 3],
    pub sum_sq: [f64; 3],
    pub count: u32,
}

impl PixelAccumulator {
    /// Adds one radiance sample.
    #[inline]
    pub fn add(&mut self, l: Rgb) {
        for c in 0..3 {
            let v = l[c] as f64;
            self.sum[c] += v;
            self.sum_sq[c] += v * v;
        }
        self.count += 1;
    }
}

impl Film {
    /// An empty film of a whole `width` × `height` image.
    pub fn new(width: u32, height: u32) -> Self {
        Film::of_region(width, height, Region::whole(width, height))
    }

    /// An empty film of `region` of a `full_width` × `full_height` image.
    pub fn of_region(full_width: u32, full_height: u32, region: Region) -> Self {
        let n = region.pixel_count();
        Film {
            width: region.width(),
            height: region.height(),
            full_width,
            full_height,
            region,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            count: vec![0; n],
        }
    }

    /// A film of `region` of a `full_width` × `full_height` image holding the given
    /// accumulators ([`Film::accumulators`], e.g. read back from a checkpoint); `None` when
    /// the region does not lie in the image or a vector's length is not its pixel count.
    pub fn from_accumulators(full_width: u32, full_height: u32, region: Region, sum: Vec<[f64; 3]>, sum_sq: Vec<[f64; 3]>, count: Vec<u32>) -> Option<Self> {
        let n = region.pixel_count();
        if !region.is_within(full_width, full_height) || sum.len() != n || sum_sq.len() != n || count.len() != n {
            return None;
        }
        Some(Film {
            width: region.width(),
            height: region.height(),
            full_width,
            full_height,
            region,
            sum,
            sum_sq,
            count,
        })
    }

    /// The accumulators, row-major from the region's top-left pixel: per-pixel sums of the
    /// samples, sums of their squares and sample counts. With [`Film::from_accumulators`]
    /// they give back the same film bit for bit.
    pub fn accumulators(&self) -> (&[[f64; 3]], &[[f64; 3]], &[u32]) {
        (&self.sum, &self.sum_sq, &self.count)
    }

    /// Adds a pass's samples of pixel `index`.
    #[inline]
    pub fn merge(&mut self, index: usize, acc: &PixelAccumulator) {
        for c in 0..3 {
            self.sum[index][c] += acc.sum[c];
            self.sum_sq[index][c] += acc.sum_sq[c];
        }
        self.count[index] += acc.count;
    }

    /// Samples taken in pixel `index`.
    pub fn samples(&self, index: usize) -> u32 {
        self.count[index]
    }

    /// Total samples over all pixels.
    pub fn total_samples(&self) -> u64 {
        self.count.iter().map(|&c| c as u64).sum()
    }

    /// The mean radiance per pixel (zero where no sample was taken).
    pub fn mean(&self) -> Vec<Rgb> {
        self.sum
            .iter()
            .zip(&self.count)
            .map(|(s, &n)| {
                if n == 0 {
                    Rgb::ZERO
                } else {
                    let k = 1.0 / n as f64;
                    Rgb::new((s[0] * k) as f32, (s[1] * k) as f32, (s[2] * k) as f32)
                }
            })
            .collect()
    }

    /// Estimated variance of each pixel's mean (sample variance / n), per channel; zero
    /// where fewer than two samples were taken.
    pub fn variance_of_mean(&self) -> Vec<Rgb> {
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .zip(&self.count)
            .map(|((s, s2), &n)| {
                if n < 2 {
                    return Rgb::ZERO;
                }
                let n = n as f64;
                let v = |c: usize| {
                    let mean = s[c] / n;
                    (((s2[c] / n - mean * mean) * n / (n - 1.0)).max(0.0) / n) as f32
                };
                Rgb::new(v(0), v(1), v(2))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_variance_of_known_samples() {
        let mut film = Film::new(2, 1);
        let mut acc = PixelAccumulator::default();
        for v in [1.0, 2.0, 3.0, 4.0] {
            acc.add(Rgb::splat(v));
        }
        film.merge(1, &acc);
        let mean = film.mean();
        assert_eq!(mean[0], Rgb::ZERO);
        assert!((mean[1] - Rgb::splat(2.5)).length() < 1e-6);
        // Sample variance 5/3, variance of the mean 5/12.
        assert!((film.variance_of_mean()[1].x - 5.0 / 12.0).abs() < 1e-6);
        assert_eq!(film.total_samples(), 4);
    }

    #[test]
    fn regions_parse_and_bands_cover_the_image_once() {
        let r: Region = "16,0,48,9".parse().unwrap();
        assert_eq!((r.width(), r.height(), r.to_string()), (32, 9, "16,0,48,9".to_string()));
        for bad in ["1,2,3", "4,0,4,9", "0,5,9,2", "a,0,1,1", "0,0,1,1,1", "-1,0,1,1"] {
            assert!(bad.parse::<Region>().is_err(), "{bad}");
        }
        for (w, h, n) in [(20, 18, 2), (64, 100, 7), (5, 16, 1), (512, 512, 32)] {
            let bands: Vec<Region> = (1..=n).map(|k| Region::band(w, h, k, n).expect("band")).collect();
            assert_eq!(bands[0].y0, 0);
            assert_eq!(bands[n as usize - 1].y1, h);
            for pair in bands.windows(2) {
                assert_eq!(pair[0].y1, pair[1].y0, "{w}x{h} in {n}");
                assert_eq!(pair[0].y1 % TILE_SIZE, 0, "bands end on tile rows");
            }
            assert!(bands.iter().all(|b| b.is_within(w, h) && (b.x0, b.x1) == (0, w)));
        }
        assert_eq!(Region::band(20, 18, 3, 3), None, "two tile rows cannot make three bands");
        assert_eq!(Region::band(20, 18, 0, 1), None);
        assert!(Region::whole(4, 4).overlaps(&"3,3,5,5".parse().unwrap()));
        assert!(!Region::whole(4, 4).overlaps(&"4,0,5,5".parse().unwrap()));
    }
}
