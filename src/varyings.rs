//! Varyings: per-vertex values a vertex shader hands to the fragment shader, interpolated
//! across triangles (perspective-correctly) and across clipped edges.

use glam::{Vec2, Vec3, Vec4};

/// A value that can be interpolated: a weighted sum of three values with weights summing to 1.
///
/// Implemented for `()`, `f32`, glam's `Vec2`/`Vec3`/`Vec4`, `[f32; N]`, and tuples of up to
/// four varyings; implement it for your own struct field by field. Varyings are plain values
/// (`'static`): the tiled backend keeps buffers of them between draw calls.
pub trait Varyings: Copy + Send + Sync + 'static {
    /// `a * w[0] + b * w[1] + c * w[2]`.
    fn weighted(a: &Self, b: &Self, c: &Self, w: [f32; 3]) -> Self;

    /// `a + (b - a) * t`, used by clipping.
    #[inline]
    fn lerp(a: &Self, b: &Self, t: f32) -> Self {
        Self::weighted(a, b, b, [1.0 - t, t, 0.0])
    }
}

impl Varyings for () {
    #[inline]
    fn weighted(_: &Self, _: &Self, _: &Self, _: [f32; 3]) -> Self {}
}

macro_rules! impl_vector_varyings {
    ($($t:ty),*) => {$(
        impl Varyings for $t {
            #[inline]
            fn weighted(a: &Self, b: &Self, c: &Self, w: [f32; 3]) -> Self {
                *a * w[0] + *b * w[1] + *c * w[2]
            }
        }
    )*};
}
impl_vector_varyings!(f32, Vec2, Vec3, Vec4);

impl<const N: usize> Varyings for [f32; N] {
    #[inline]
    fn weighted(a: &Self, b: &Self, c: &Self, w: [f32; 3]) -> Self {
        std::array::from_fn(|i| a[i] * w[0] + b[i] * w[1] + c[i] * w[2])
    }
}

macro_rules! impl_tuple_varyings {
    ($($name:ident $idx:tt),*) => {
        impl<$($name: Varyings),*> Varyings for ($($name,)*) {
            #[inline]
            fn weighted(a: &Self, b: &Self, c: &Self, w: [f32; 3]) -> Self {
                ($($name::weighted(&a.$idx, &b.$idx, &c.$idx, w),)*)
            }
        }
    };
}
impl_tuple_varyings!(A 0);
impl_tuple_varyings!(A 0, B 1);
impl_tuple_varyings!(A 0, B 1, C 2);
impl_tuple_varyings!(A 0, B 1, C 2, D 3);
