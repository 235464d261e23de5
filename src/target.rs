//! Render targets: the buffers the shade stage writes, laid out row-major, row 0 at the top.

use crate::error::Error;
use crate::fixed::MAX_TARGET_SIZE;
use crate::setup::PixelRect;

/// Colour, depth and the optional id and overdraw buffers of one image.
#[derive(Clone, Debug)]
pub struct Target {
    width: u32,
    height: u32,
    /// RGBA8 colour, `width * height` pixels.
    pub color: Vec<[u8; 4]>,
    /// Depth, cleared to 1.0.
    pub depth: Vec<f32>,
    /// Index of the triangle whose fragment was last written (passed the depth test) at each
    /// pixel, -1 where none was.
    pub ids: Option<Vec<i32>>,
    /// Fragments generated per pixel, counted before the depth test.
    pub overdraw: Option<Vec<u32>>,
    /// Normal of the last written fragment (zero where none), when a pipeline provides one.
    pub normals: Option<Vec<[f32; 3]>>,
}

/// The colour a new target is cleared to: opaque black.
pub const DEFAULT_CLEAR_COLOR: [u8; 4] = [0, 0, 0, 255];

impl Target {
    /// A `width x height` target with colour and depth; both sides must be in
    /// `1..=16384` (the range the fixed-point bound is derived for).
    pub fn new(width: u32, height: u32) -> Result<Self, Error> {
        if !(1..=MAX_TARGET_SIZE).contains(&width) || !(1..=MAX_TARGET_SIZE).contains(&height) {
            return Err(Error::TargetSize { width, height });
        }
        let n = width as usize * height as usize;
        Ok(Self {
            width,
            height,
            color: vec![DEFAULT_CLEAR_COLOR; n],
            depth: vec![1.0; n],
            ids: None,
            overdraw: None,
            normals: None,
        })
    }

    /// Adds a triangle-id buffer, cleared to -1.
    #[must_use]
    pub fn with_ids(mut self) -> Self {
        self.ids = Some(vec![-1; self.pixel_count()]);
        self
    }

    /// Adds an overdraw buffer, cleared to 0.
    #[must_use]
    pub fn with_overdraw(mut self) -> Self {
        self.overdraw = Some(vec![0; self.pixel_count()]);
        self
    }

    /// Adds a normal buffer, cleared to zero.
    #[must_use]
    pub fn with_normals(mut self) -> Self {
        self.normals = Some(vec![[0.0; 3]; self.pixel_count()]);
        self
    }

    /// Clears colour to `color`, depth to 1.0, ids to -1, overdraw and normals to 0.
    pub fn clear(&mut self, color: [u8; 4]) {
        self.color.fill(color);
        self.depth.fill(1.0);
        if let Some(ids) = &mut self.ids {
            ids.fill(-1);
        }
        if let Some(o) = &mut self.overdraw {
            o.fill(0);
        }
        if let Some(n) = &mut self.normals {
            n.fill([0.0; 3]);
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

    /// Index of pixel `(x, y)` in the buffers.
    #[inline]
    #[must_use]
    pub fn index(&self, x: i32, y: i32) -> usize {
        y as usize * self.width as usize + x as usize
    }
}
