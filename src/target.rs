//! Render targets: the buffers the shade stage writes, laid out row-major, row 0 at the top.
//!
//! Per-sample buffers (colour, depth, ids) hold `samples` consecutive values per pixel: element
//! `pixel * samples + s`, i.e. an array of shape (height, width, samples). Per-pixel buffers
//! (overdraw, normals) hold one.

use std::any::Any;

use rayon::prelude::*;

use crate::color::{linear_to_srgb8, srgb_to_linear};
use crate::error::Error;
use crate::fixed::MAX_TARGET_SIZE;
use crate::render::Schedule;
use crate::sample::SampleCount;
use crate::setup::PixelRect;
use crate::simd;

/// Colour, depth and the optional id, overdraw and normal buffers of one image.
///
/// A target also keeps the tiled backend's batch buffers between draw calls (see
/// [`Target::release_scratch`]), and how the banded schedule shares work among its threads
/// ([`crate::band::BandBalance`], from the times of earlier draw calls; never what is drawn).
#[derive(Clone, Debug)]
pub struct Target {
    width: u32,
    height: u32,
    samples: SampleCount,
    /// RGBA8 colour per sample (sRGB-encoded where the pipeline is colour-managed).
    pub color: Vec<[u8; 4]>,
    /// Depth per sample, cleared to 1.0.
    pub depth: Vec<f32>,
    /// Per sample, the index of the triangle whose fragment was last written there (passed the
    /// depth test), -1 where none was.
    pub ids: Option<Vec<i32>>,
    /// Covered samples per pixel, counted before the depth test (fragments, at 1x).
    pub overdraw: Option<Vec<u32>>,
    /// Normal of the last written fragment (zero where none), when a pipeline provides one.
    pub normals: Option<Vec<[f32; 3]>>,
    scratch: Scratch,
    /// How the last draw call spread its triangles over threads (see
    /// [`Target::last_schedule`]).
    schedule: Option<Schedule>,
    /// The banded schedule's shares of work per band, from the last banded draw calls' times.
    pub(crate) balance: crate::band::BandBalance,
}

/// Memory a draw call leaves for the next one on the same target: the tiled backend's
/// per-batch buffers (two batches of set-up triangles: about 64 MB when a draw call has a
/// million flat or smooth window triangles that all make records, more for perspective
/// colours or 3D varyings; [`Target::release_scratch`] frees them). Writing a frame's records
/// into freshly allocated memory faulted in (and zeroed) every page of it again each frame: a
/// tenth of the time of a million small triangles. Type-erased because each pipeline keeps
/// records of its own type; a draw that finds another type starts afresh.
#[derive(Default)]
struct Scratch(Option<Box<dyn Any + Send + Sync>>);

impl Clone for Scratch {
    /// A clone starts without scratch memory: it is a cache, not part of the image.
    fn clone(&self) -> Self {
        Self(None)
    }
}

impl std::fmt::Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() { "Scratch(kept)" } else { "Scratch(empty)" })
    }
}

/// Sets every element of `buffer` to `value`, blocks of 256 KB in parallel (a buffer of one
/// block on the calling thread, without a trip to the pool).
fn par_fill<T: Copy + Send + Sync>(buffer: &mut [T], value: T, fill: impl Fn(&mut [T], T) + Sync) {
    let block = (256 << 10) / size_of::<T>();
    if buffer.len() <= block {
        fill(buffer, value);
    } else {
        buffer.par_chunks_mut(block).for_each(|b| fill(b, value));
    }
}

/// The colour a new target is cleared to: opaque black.
pub const DEFAULT_CLEAR_COLOR: [u8; 4] = [0, 0, 0, 255];

impl Target {
    /// A `width x height` target with colour and depth; both sides must be in
    /// `1..=16384` (the range the fixed-point bound is derived for).
    pub fn new(width: u32, height: u32) -> Result<Self, Error> {
        Self::multisampled(width, height, SampleCount::X1)
    }

    /// A target with `samples` samples per pixel for colour, depth and ids.
    pub fn multisampled(width: u32, height: u32, samples: SampleCount) -> Result<Self, Error> {
        if !(1..=MAX_TARGET_SIZE).contains(&width) || !(1..=MAX_TARGET_SIZE).contains(&height) {
            return Err(Error::TargetSize { width, height });
        }
        let n = width as usize * height as usize * samples.count();
        // A 16384 x 16384 target at 8x takes 17 GB: report what cannot be had instead of
        // aborting the process.
        let too_large = |_| Error::TargetMemory { width, height, samples: samples.count() };
        let mut color = Vec::new();
        color.try_reserve_exact(n).map_err(too_large)?;
        color.resize(n, DEFAULT_CLEAR_COLOR);
        let mut depth = Vec::new();
        depth.try_reserve_exact(n).map_err(too_large)?;
        depth.resize(n, 1.0);
        Ok(Self {
            width,
            height,
            samples,
            color,
            depth,
            ids: None,
            overdraw: None,
            normals: None,
            scratch: Scratch::default(),
            schedule: None,
            balance: crate::band::BandBalance::default(),
        })
    }

    /// Frees the memory the tiled backend keeps between draw calls (it is kept so that the
    /// next frame does not fault in fresh pages); the next draw call allocates it again.
    pub fn release_scratch(&mut self) {
        self.scratch = Scratch::default();
    }

    /// Takes the scratch a previous draw call left, if it is a `T`; otherwise a new `T`.
    pub(crate) fn take_scratch<T: Default + Send + Sync + 'static>(&mut self) -> T {
        match self.scratch.0.take().map(|b| b.downcast::<T>()) {
            Some(Ok(kept)) => *kept,
            _ => T::default(),
        }
    }

    /// Leaves `scratch` for the next draw call.
    pub(crate) fn keep_scratch<T: Send + Sync + 'static>(&mut self, scratch: T) {
        self.scratch = Scratch(Some(Box::new(scratch)));
    }

    /// How the tiled backend spread the last call of [`crate::render::draw`] or
    /// [`crate::pipeline::Pipeline::draw`] on this target over threads (the calls every
    /// triangle draw goes through, `model::render_mesh`'s and the polygon fills' among them):
    /// [`Schedule::Binned`] or [`Schedule::Banded`], what [`Schedule::Auto`] chose. `None`
    /// before any such call, and after one on the reference backend or one that failed.
    /// Splat rendering does not change it. For benchmarks and tuning: every schedule draws the
    /// same pixels.
    #[must_use]
    pub fn last_schedule(&self) -> Option<Schedule> {
        self.schedule
    }

    /// Records how the draw call being made is scheduled (`None` as it starts).
    pub(crate) fn set_schedule(&mut self, schedule: Option<Schedule>) {
        self.schedule = schedule;
    }

    /// Adds a triangle-id buffer, cleared to -1. Aborts, as `vec!` does, when it cannot be
    /// allocated ([`Target::try_with_ids`] reports that instead).
    #[must_use]
    pub fn with_ids(mut self) -> Self {
        self.ids = Some(vec![-1; self.pixel_count() * self.samples.count()]);
        self
    }

    /// Adds an overdraw buffer, cleared to 0 (see [`Target::with_ids`]).
    #[must_use]
    pub fn with_overdraw(mut self) -> Self {
        self.overdraw = Some(vec![0; self.pixel_count()]);
        self
    }

    /// Adds a normal buffer, cleared to zero (see [`Target::with_ids`]).
    #[must_use]
    pub fn with_normals(mut self) -> Self {
        self.normals = Some(vec![[0.0; 3]; self.pixel_count()]);
        self
    }

    /// [`Target::with_ids`], or [`Error::OutOfMemory`] naming the buffer where it cannot be
    /// had (a 16384 x 16384 target's ids take 1 GiB a sample: the size comes from the user).
    pub fn try_with_ids(mut self) -> Result<Self, Error> {
        self.ids = Some(self.filled(self.pixel_count() * self.samples.count(), -1, "ids")?);
        Ok(self)
    }

    /// [`Target::with_overdraw`], or [`Error::OutOfMemory`] (see [`Target::try_with_ids`]).
    pub fn try_with_overdraw(mut self) -> Result<Self, Error> {
        self.overdraw = Some(self.filled(self.pixel_count(), 0, "overdraw")?);
        Ok(self)
    }

    /// [`Target::with_normals`], or [`Error::OutOfMemory`] (see [`Target::try_with_ids`]).
    pub fn try_with_normals(mut self) -> Result<Self, Error> {
        self.normals = Some(self.filled(self.pixel_count(), [0.0; 3], "normals")?);
        Ok(self)
    }

    /// `n` copies of `value` for the buffer named `buffer`, allocated fallibly and filled in
    /// parallel (a 16384 x 16384 normal buffer is 3 GiB).
    fn filled<T: Copy + Send + Sync>(
        &self,
        n: usize,
        value: T,
        buffer: &str,
    ) -> Result<Vec<T>, Error> {
        let mut v = Vec::new();
        crate::error::try_reserve_named(&mut v, n, || {
            format!("the {buffer} buffer of a {}x{} target", self.width, self.height)
        })?;
        v.par_extend(rayon::iter::repeat_n(value, n));
        Ok(v)
    }

    /// Clears colour to `color`, depth to 1.0, ids to -1, overdraw and normals to 0, in
    /// parallel on the current rayon pool (a 1080p target at 4x holds 66 MB of colour and
    /// depth: 7 ms of one thread), with string stores where the CPU makes them fast
    /// ([`simd::fill_words`]).
    pub fn clear(&mut self, color: [u8; 4]) {
        par_fill(&mut self.color, color, simd::fill_words);
        par_fill(&mut self.depth, 1.0, simd::fill_words);
        if let Some(ids) = &mut self.ids {
            par_fill(ids, -1, simd::fill_words);
        }
        if let Some(o) = &mut self.overdraw {
            par_fill(o, 0, simd::fill_words);
        }
        if let Some(n) = &mut self.normals {
            par_fill(n, [0.0; 3], <[_]>::fill);
        }
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Checks that every buffer has its length: one entry per sample for colour, depth and
    /// ids, one per pixel for overdraw and normals. The buffers are public fields, and a draw
    /// into one replaced by a shorter one had indexed past its end.
    ///
    /// # Errors
    /// [`Error::TargetBuffer`] naming the first that does not.
    pub fn check_buffers(&self) -> Result<(), Error> {
        let pixels = self.pixel_count();
        let samples = pixels * self.samples.count();
        let buffers = [
            ("colour", Some(self.color.len()), samples),
            ("depth", Some(self.depth.len()), samples),
            ("id", self.ids.as_ref().map(Vec::len), samples),
            ("overdraw", self.overdraw.as_ref().map(Vec::len), pixels),
            ("normal", self.normals.as_ref().map(Vec::len), pixels),
        ];
        for (buffer, len, expected) in buffers {
            if let Some(len) = len.filter(|&len| len != expected) {
                return Err(Error::TargetBuffer { buffer, len, expected });
            }
        }
        Ok(())
    }

    /// [`Target::check_buffers`] as a panic, for the items that hand out the buffers as
    /// bands (the drawing entry points check first and return the error).
    fn assert_buffers(&self) {
        if let Err(e) = self.check_buffers() {
            panic!("{e}");
        }
    }

    /// `width * height`.
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The whole target as a pixel rectangle.
    #[must_use]
    pub fn rect(&self) -> PixelRect {
        PixelRect::of_target(self.width, self.height)
    }

    /// Samples per pixel.
    #[must_use]
    pub fn samples(&self) -> SampleCount {
        self.samples
    }

    /// The colour image: at 1x the colour buffer itself; with multisampling, each pixel's
    /// samples averaged in linear light (colour decoded from sRGB, averaged, encoded again;
    /// alpha averaged as is). Pixels are resolved in parallel on the current rayon pool.
    ///
    /// # Panics
    /// If the colour buffer was replaced by one of another length: the image would have
    /// been of another size, without a word.
    #[must_use]
    pub fn resolve(&self) -> Vec<[u8; 4]> {
        let n = self.samples.count();
        let expected = self.pixel_count() * n;
        assert_eq!(self.color.len(), expected, "resolve: the colour buffer's length");
        if n == 1 {
            return self.color.clone();
        }
        let mut image = Vec::with_capacity(self.pixel_count());
        self.color
            .par_chunks_exact(n)
            .with_min_len(1024)
            .map(resolve_pixel)
            .collect_into_vec(&mut image);
        image
    }

    /// Sample `s` of every pixel of a per-sample buffer, as a per-pixel image.
    ///
    /// # Panics
    /// If `s` is not below the sample count or `buffer` is not a per-sample buffer.
    #[must_use]
    pub fn sample_plane<T: Copy>(&self, buffer: &[T], s: usize) -> Vec<T> {
        let n = self.samples.count();
        assert!(s < n && buffer.len() == self.pixel_count() * n, "not a per-sample buffer");
        buffer.iter().skip(s).step_by(n).copied().collect()
    }

    /// Index of pixel `(x, y)` in per-pixel buffers (and in per-sample ones at 1x). The pixel
    /// must lie in the target (asserted in debug builds): the index of one outside it is
    /// meaningless, another pixel's or past the buffers (`(-1, 1)` wraps to `(width - 1, 0)`).
    #[inline]
    #[must_use]
    pub fn index(&self, x: i32, y: i32) -> usize {
        debug_assert!(
            (0..self.width as i32).contains(&x) && (0..self.height as i32).contains(&y),
            "pixel ({x}, {y}) outside the {}x{} target",
            self.width,
            self.height
        );
        y as usize * self.width as usize + x as usize
    }
}

/// A horizontal band of a target's rows with mutable views of all its buffers: the part of an
/// image one thread writes. Bands from [`Target::bands`] (or [`Target::bands_from`]) are
/// disjoint slices, so threads write them at the same time without locks or `unsafe`.
#[derive(Debug)]
pub struct TargetBand<'a> {
    rect: PixelRect,
    width: usize,
    samples: SampleCount,
    /// Colour per sample of the band's rows.
    pub color: &'a mut [[u8; 4]],
    /// Depth per sample.
    pub depth: &'a mut [f32],
    /// Ids per sample, when the target has them.
    pub ids: Option<&'a mut [i32]>,
    /// Overdraw per pixel, when the target has it.
    pub overdraw: Option<&'a mut [u32]>,
    /// Normals per pixel, when the target has them.
    pub normals: Option<&'a mut [[f32; 3]]>,
}

impl TargetBand<'_> {
    /// Starts loading the buffers' cache lines for the pixels of `rect` (within the band):
    /// the tile loop calls it before a tile's triangles, which would otherwise wait on
    /// memory row by row, one triangle after another.
    pub fn prefetch(&self, rect: &PixelRect) {
        let n = self.samples.count();
        for y in rect.y0..=rect.y1 {
            let (a, b) = (self.index(rect.x0, y), self.index(rect.x1, y) + 1);
            crate::simd::prefetch_slice(&self.depth[a * n..b * n]);
            crate::simd::prefetch_slice(&self.color[a * n..b * n]);
            if let Some(ids) = &self.ids {
                crate::simd::prefetch_slice(&ids[a * n..b * n]);
            }
            if let Some(o) = &self.overdraw {
                crate::simd::prefetch_slice(&o[a..b]);
            }
        }
    }

    /// The band's pixels: full width, its rows.
    #[must_use]
    pub fn rect(&self) -> PixelRect {
        self.rect
    }

    /// Samples per pixel.
    #[must_use]
    pub fn samples(&self) -> SampleCount {
        self.samples
    }

    /// The largest depth stored at the pixels of `rect` (within the band; every sample); NaN
    /// depths are ignored (no depth passes a test against them), `-inf` when there are only
    /// those.
    #[must_use]
    pub fn max_depth(&self, rect: &PixelRect) -> f32 {
        let n = self.samples.count();
        // Eight running maxima, so that the loop compiles to vector maxima.
        let mut lanes = [f32::NEG_INFINITY; 8];
        for y in rect.y0..=rect.y1 {
            let row = &self.depth[self.index(rect.x0, y) * n..(self.index(rect.x1, y) + 1) * n];
            let chunks = row.chunks_exact(8);
            for &z in chunks.remainder() {
                lanes[0] = lanes[0].max(z);
            }
            for chunk in chunks {
                for (m, &z) in lanes.iter_mut().zip(chunk) {
                    *m = m.max(z);
                }
            }
        }
        lanes.into_iter().fold(f32::NEG_INFINITY, f32::max)
    }

    /// Elements from one row to the next in per-pixel buffers (the target's width).
    #[inline]
    #[must_use]
    pub fn stride(&self) -> usize {
        self.width
    }

    /// Index of pixel `(x, y)` (image coordinates) in per-pixel buffers. The pixel must lie in
    /// the band (asserted in debug builds), as for [`Target::index`].
    #[inline]
    #[must_use]
    pub fn index(&self, x: i32, y: i32) -> usize {
        debug_assert!(
            (self.rect.x0..=self.rect.x1).contains(&x)
                && (self.rect.y0..=self.rect.y1).contains(&y),
            "pixel ({x}, {y}) outside the band {:?}",
            self.rect
        );
        (y - self.rect.y0) as usize * self.width + x as usize
    }
}

impl Target {
    /// The whole target as one band.
    ///
    /// # Panics
    /// If a buffer does not have its length ([`Target::check_buffers`]): a band's kernels
    /// index its buffers by the target's size.
    pub fn band(&mut self) -> TargetBand<'_> {
        self.assert_buffers();
        let rect = self.rect();
        TargetBand {
            rect,
            width: self.width as usize,
            samples: self.samples,
            color: &mut self.color,
            depth: &mut self.depth,
            ids: self.ids.as_deref_mut(),
            overdraw: self.overdraw.as_deref_mut(),
            normals: self.normals.as_deref_mut(),
        }
    }

    /// The target split into bands of `rows` rows (the last may be shorter), top to bottom.
    ///
    /// # Panics
    /// If `rows` is 0, or as [`Target::bands_from`].
    pub fn bands(&mut self, rows: u32) -> Vec<TargetBand<'_>> {
        assert!(rows > 0, "bands need at least one row");
        let starts: Vec<u32> = (0..self.height).step_by(rows as usize).collect();
        self.bands_from(&starts)
    }

    /// The target split into bands starting at rows `starts` (ascending, the first 0), each
    /// reaching to the next one's start or the bottom.
    ///
    /// # Panics
    /// If `starts` does not begin with 0, is not strictly ascending, or reaches past the last
    /// row, or if a buffer does not have its length ([`Target::check_buffers`]).
    pub fn bands_from(&mut self, starts: &[u32]) -> Vec<TargetBand<'_>> {
        self.assert_buffers();
        let h = self.height;
        let ascending = starts.windows(2).all(|w| w[0] < w[1]);
        assert!(
            starts.first() == Some(&0) && ascending && starts.last().is_some_and(|&l| l < h),
            "band starts {starts:?} do not cut rows 0..{h}"
        );
        let (w, n) = (self.width as usize, self.samples.count());
        let ends = starts.iter().skip(1).chain([&h]);
        let rows: Vec<usize> = starts.iter().zip(ends).map(|(s, e)| (e - s) as usize).collect();
        // A buffer of `per_row` elements per row, cut into the bands' pieces.
        fn cut<'b, T>(mut rest: &'b mut [T], per_row: usize, rows: &[usize]) -> Vec<&'b mut [T]> {
            rows.iter()
                .map(|&r| {
                    let (piece, tail) = std::mem::take(&mut rest).split_at_mut(r * per_row);
                    rest = tail;
                    piece
                })
                .collect()
        }
        let color = cut(&mut self.color, w * n, &rows);
        let depth = cut(&mut self.depth, w * n, &rows);
        // Optional buffers: their pieces, or none for every band.
        let mut ids = self.ids.as_deref_mut().map(|b| cut(b, w * n, &rows).into_iter());
        let mut overdraw = self.overdraw.as_deref_mut().map(|b| cut(b, w, &rows).into_iter());
        let mut normals = self.normals.as_deref_mut().map(|b| cut(b, w, &rows).into_iter());
        let samples = self.samples;
        color
            .into_iter()
            .zip(depth)
            .enumerate()
            .map(|(k, (color, depth))| {
                let y0 = starts[k] as i32;
                TargetBand {
                    rect: PixelRect { x0: 0, y0, x1: w as i32 - 1, y1: y0 + rows[k] as i32 - 1 },
                    width: w,
                    samples,
                    color,
                    depth,
                    ids: ids.as_mut().and_then(Iterator::next),
                    overdraw: overdraw.as_mut().and_then(Iterator::next),
                    normals: normals.as_mut().and_then(Iterator::next),
                }
            })
            .collect()
    }
}

/// One pixel of [`Target::resolve`]. Most pixels of a multisampled image are covered by one
/// triangle or none, their samples all one colour, and such a pixel resolves to that colour:
/// the average of `n` copies of a decoded value is that value within a rounding or two, and
/// every decoded value lies half an 8-bit step from where the encoder rounds to a neighbour
/// (`uniform_pixels_resolve_to_their_colour` checks every value at every sample count). So
/// the average is computed only at edges (at 1080p and 4x it had taken 100 ms, three times
/// the frame).
fn resolve_pixel(samples: &[[u8; 4]]) -> [u8; 4] {
    let first = samples[0];
    if samples.iter().all(|&c| c == first) { first } else { average_in_linear_light(samples) }
}

/// Samples averaged in linear light: colour decoded from sRGB, averaged and encoded again,
/// alpha averaged as is.
fn average_in_linear_light(samples: &[[u8; 4]]) -> [u8; 4] {
    let mut sum = [0.0f32; 4];
    for c in samples {
        for k in 0..3 {
            sum[k] += srgb_to_linear(c[k]);
        }
        sum[3] += f32::from(c[3]);
    }
    let k = samples.len() as f32;
    [
        linear_to_srgb8(sum[0] / k),
        linear_to_srgb8(sum[1] / k),
        linear_to_srgb8(sum[2] / k),
        (sum[3] / k).round() as u8,
    ]
}

#[cfg(test)]
impl Target {
    /// A `width x height` target (with ids and overdraw if `extra`) whose depths are random
    /// in [0, 1): what the kernels' tests draw into.
    pub(crate) fn random_depths(
        width: u32,
        height: u32,
        extra: bool,
        rng: &mut impl rand::Rng,
    ) -> Self {
        let mut target = Self::new(width, height).expect("a test target");
        if extra {
            target = target.with_ids().with_overdraw();
        }
        for d in &mut target.depth {
            *d = rng.random_range(0.0..1.0);
        }
        target
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A colour buffer replaced by one of another length is refused by name, at 1x and
    /// multisampled, where the image had come out of another size.
    #[test]
    fn resolving_a_replaced_colour_buffer_panics() {
        for samples in [SampleCount::X1, SampleCount::X4] {
            let mut target = Target::multisampled(8, 4, samples).unwrap();
            target.color.pop();
            let caught =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| target.resolve()));
            let message = caught.unwrap_err().downcast::<String>().unwrap();
            assert!(message.contains("colour buffer"), "{message}");
        }
    }

    /// Bands of a target whose buffer was replaced by one of another length are refused with
    /// the buffer's name, longer or shorter (a shorter one had panicked in `split_at_mut`, a
    /// longer one been cut without a word).
    #[test]
    fn bands_of_replaced_buffers_panic_naming_them() {
        type Replace = fn(&mut Target);
        let cases: [(Replace, &str); 3] = [
            (|t| t.depth.truncate(5), "depth buffer has 5 entries where 32 are needed"),
            (|t| t.color.push([0; 4]), "colour buffer has 33 entries"),
            (|t| t.overdraw = Some(vec![0; 31]), "overdraw buffer has 31 entries"),
        ];
        for (replace, want) in cases {
            let take: [fn(&mut Target); 3] =
                [|t| _ = t.band(), |t| _ = t.bands(3), |t| _ = t.bands_from(&[0, 1])];
            for take in take {
                let mut target = Target::new(8, 4).unwrap();
                take(&mut target);
                replace(&mut target);
                let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    take(&mut target);
                }));
                let message = caught.unwrap_err().downcast::<String>().unwrap();
                assert!(message.contains(want), "{message}");
            }
        }
    }

    /// The shortcut of `resolve_pixel`: a pixel whose samples are all one colour averages to
    /// that colour, for every 8-bit value in every channel (colour and alpha) at every sample
    /// count; and pixels that differ in one sample still go through the average.
    #[test]
    fn uniform_pixels_resolve_to_their_colour() {
        for samples in [SampleCount::X4, SampleCount::X8] {
            let n = samples.count();
            for v in 0..=255u8 {
                let pixel = vec![[v; 4]; n];
                assert_eq!(average_in_linear_light(&pixel), [v; 4], "{v} at {n}x");
            }
            let mut target = Target::multisampled(3, 1, samples).unwrap();
            target.color.fill([255, 0, 0, 255]);
            target.color[n] = [0, 0, 255, 0];
            target.color[2 * n..].fill([0, 128, 0, 255]);
            let red_blue = average_in_linear_light(&target.color[n..2 * n]);
            assert_ne!(red_blue, [255, 0, 0, 255]);
            assert_eq!(target.resolve(), vec![[255, 0, 0, 255], red_blue, [0, 128, 0, 255]]);
        }
    }

    /// The fallible buffer constructors give the buffers the infallible ones give, and where
    /// one cannot be had, an error naming it.
    #[test]
    fn fallible_buffers_match() {
        for samples in [SampleCount::X1, SampleCount::X4] {
            let t = Target::multisampled(7, 5, samples).unwrap();
            let a = t.clone().with_ids().with_overdraw().with_normals();
            let b =
                t.try_with_ids().unwrap().try_with_overdraw().unwrap().try_with_normals().unwrap();
            assert_eq!(a.ids, b.ids);
            assert_eq!(a.overdraw, b.overdraw);
            assert_eq!(a.normals, b.normals);
            assert_eq!(b.ids.as_ref().map(Vec::len), Some(35 * samples.count()));
        }
        let t = Target::new(7, 5).unwrap();
        crate::error::refusals::refuse_after(Some(0));
        let e = t.try_with_normals().unwrap_err().to_string();
        assert_eq!(e, "not enough memory for the normals buffer of a 7x5 target: 0.0 GiB");
    }

    /// Bands cut every buffer at their rows: a band's rectangle and each of its buffers hold
    /// exactly its rows (per sample or per pixel), so that writing the band's number at every
    /// element of each band leaves row `y` of the target holding the number of the band that
    /// starts at or above it; `bands(rows)` is `bands_from` every `rows` rows.
    #[test]
    fn bands_cut_every_buffer_at_their_rows() {
        let fresh = || {
            let target = Target::multisampled(7, 10, SampleCount::X4).unwrap();
            target.with_ids().with_overdraw().with_normals()
        };
        for starts in [vec![0], vec![0, 1], vec![0, 3, 4, 9], (0..10).collect()] {
            let mut target = fresh();
            for (k, band) in target.bands_from(&starts).into_iter().enumerate() {
                let rows = starts.get(k + 1).copied().unwrap_or(10) - starts[k];
                let r = band.rect();
                assert_eq!(
                    (r.x0, r.y0, r.x1, r.y1),
                    (0, starts[k] as i32, 6, (starts[k] + rows) as i32 - 1)
                );
                let per_pixel = 7 * rows as usize;
                assert_eq!(band.color.len(), 4 * per_pixel);
                band.color.fill([k as u8; 4]);
                band.depth.fill(k as f32);
                band.ids.unwrap().fill(k as i32);
                band.overdraw.unwrap().fill(k as u32);
                band.normals.unwrap().fill([k as f32; 3]);
            }
            let band_of = |y: usize| starts.iter().rposition(|&s| s as usize <= y).unwrap();
            for y in 0..10 {
                let k = band_of(y);
                let (samples, pixels) = (28 * y..28 * (y + 1), 7 * y..7 * (y + 1));
                assert!(
                    target.color[samples.clone()].iter().all(|c| *c == [k as u8; 4]),
                    "{starts:?} row {y}"
                );
                assert!(target.depth[samples.clone()].iter().all(|&d| d == k as f32));
                assert!(target.ids.as_ref().unwrap()[samples].iter().all(|&i| i == k as i32));
                assert!(
                    target.overdraw.as_ref().unwrap()[pixels.clone()]
                        .iter()
                        .all(|&o| o == k as u32)
                );
                assert!(
                    target.normals.as_ref().unwrap()[pixels].iter().all(|&n| n == [k as f32; 3])
                );
            }
        }
        let mut target = fresh();
        let rects: Vec<PixelRect> = target.bands(4).iter().map(TargetBand::rect).collect();
        let mut same = fresh();
        let expected: Vec<PixelRect> =
            same.bands_from(&[0, 4, 8]).iter().map(TargetBand::rect).collect();
        assert_eq!(rects, expected);
    }

    /// Starts that do not cut the rows (not from 0, not ascending, past the last row) are a
    /// programming error, caught before any buffer is split.
    #[test]
    fn bands_need_starts_that_cut_the_rows() {
        for starts in [&[][..], &[1], &[0, 0], &[0, 5, 3], &[0, 10]] {
            let result =
                std::panic::catch_unwind(|| Target::new(7, 10).unwrap().bands_from(starts).len());
            assert!(result.is_err(), "{starts:?}");
        }
    }
}
