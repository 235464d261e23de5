//! The compact `.tsplat` file format: a [`SplatTree`] in 6 bytes per node (QSplat style).
//!
//! The exact byte layout, the quantization and the error bounds are documented in
//! `docs/tsplat.md`; in short:
//!
//! * a 52-byte little-endian header: magic `TSPLAT\0\0`, version 1, flags (normals present,
//!   colours present), node count, leaf count, the root sphere as four `f32`, and a CRC-32 of
//!   every other byte of the file;
//! * then one 48-bit word per node, breadth-first, root first: a 16-bit *structure code*
//!   (the node's sphere relative to its parent's decoded sphere, times 5, plus its child count
//!   0..=4), a 7+7-bit octahedral normal, a 2-bit normal-cone bucket and an RGB565 colour.
//!
//! A child's centre is one of 13 levels per axis across `[-R, +R]` of the *decoded* parent
//! sphere (radius `R`) and its radius one of 13 levels `k R / 12`; only the 11297
//! (centre, radius) pairs with `2 |q - 6| + k <= 17` (`q` the three centre levels, `|.|`
//! Euclidean: the sphere reaches at most `17/12 R` from the parent's centre) can occur, which is
//! what leaves room for the child count in 16 bits. Encoding is conservative: working top-down
//! against the decoded parent, each child gets the smallest decoded sphere that contains the
//! true sphere of every node in its subtree (measured exactly, not through bounds of bounds),
//! so the decoded tree bounds every point and every leaf splat. The parent's decoded sphere
//! itself is always such a sphere (it contains the parent's whole subtree), and it has a code
//! of its own, which is why every node has one. Normal cones are rounded up by the normal's
//! quantization error, so culling stays conservative too.
//!
//! [`encode`] allocates fallibly: an array the allocator refuses (they are proportional to the
//! node count, and the encoder's work arrays take about three times the tree's own memory) is
//! [`Error::OutOfMemory`] naming it, not an abort. [`decode`] never panics and never allocates
//! more than the input's length justifies, and reports a refused allocation too; its errors
//! ([`FormatError`]) carry the byte offset of the problem.

use std::f32::consts::PI;
use std::fmt;
use std::path::Path;

use rayon::prelude::*;

use super::tree::{SplatNode, SplatTree};
use crate::error::{Error, try_reserve_named};

/// Bytes per stored node (48 bits).
pub const BYTES_PER_NODE: usize = 6;
/// Bytes in the header, before the first node.
pub const HEADER_BYTES: usize = 52;
/// The first 8 bytes of every `.tsplat` file.
pub const MAGIC: [u8; 8] = *b"TSPLAT\0\0";
/// The format version this module writes and reads.
pub const VERSION: u32 = 1;
/// Header flag: the nodes carry normals and normal cones (otherwise every decoded normal is
/// zero and every cone is pi).
pub const FLAG_NORMALS: u32 = 1;
/// Header flag: the nodes carry colours (otherwise every decoded colour is white).
pub const FLAG_COLORS: u32 = 2;
/// The normal-cone half-angle each 2-bit cone bucket decodes to, radians (`pi` means "any
/// direction": never cull). The encoder picks the first bucket at least as wide as the true
/// cone plus the normal's quantization error.
pub const CONE_BUCKETS: [f32; 4] = [PI / 32.0, PI / 8.0, PI / 4.0, PI];

const OFFSET_VERSION: usize = 8;
const OFFSET_FLAGS: usize = 12;
const OFFSET_NODE_COUNT: usize = 16;
const OFFSET_LEAF_COUNT: usize = 24;
const OFFSET_ROOT: usize = 32;
const OFFSET_CHECKSUM: usize = 48;
/// Relative slack on every distance the encoder measures (f64 distances between f32 points are
/// within a few ulps, ~1e-16, of the exact ones), so containment holds in exact arithmetic and
/// when re-checked in f64 in any order. Exact fits (equal centres) need no slack.
const MARGIN: f64 = 1e-12;
/// Normal level reserved for "no normal".
const NO_NORMAL: u8 = 127;

// ---------------------------------------------------------------------------------------------
// Errors

/// Why [`decode`] rejected its input, and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FormatError {
    /// Byte offset of the problem in the input (for a truncated file: its length).
    pub offset: usize,
    /// What is wrong.
    pub kind: FormatErrorKind,
}

/// The kinds of [`FormatError`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FormatErrorKind {
    /// The input ends before the part it is in is complete.
    #[error("file ends inside the {part}: {expected} bytes expected, the file has fewer")]
    Truncated {
        /// "magic", "header" or "node data".
        part: &'static str,
        /// The length the file needs at least.
        expected: u64,
    },
    /// The first 8 bytes are not [`MAGIC`].
    #[error("not a .tsplat file: the first 8 bytes must be `TSPLAT\\0\\0`")]
    BadMagic,
    /// A version other than [`VERSION`].
    #[error("unsupported .tsplat version {0}: this reader understands version 1")]
    UnsupportedVersion(u32),
    /// Flag bits other than [`FLAG_NORMALS`] and [`FLAG_COLORS`].
    #[error("unknown header flags {0:#x}: only 0x1 (normals) and 0x2 (colours) are defined")]
    UnknownFlags(u32),
    /// More nodes than 32-bit child indices can address.
    #[error("node count {0} is too large: at most 4294967295 nodes")]
    NodeCountOverflow(u64),
    /// Bytes after the last node.
    #[error("{extra} bytes after the last of {nodes} nodes")]
    TrailingBytes {
        /// Number of extra bytes.
        extra: u64,
        /// Node count from the header.
        nodes: u64,
    },
    /// The root sphere in the header is not finite or has a negative radius.
    #[error("root sphere {centre:?} radius {radius} is not finite or has a negative radius")]
    BadRoot {
        /// The stored centre, formatted.
        centre: String,
        /// The stored radius, formatted.
        radius: String,
    },
    /// The checksum field does not match the data.
    #[error(
        "checksum mismatch: header says {stored:#010x}, the data gives {computed:#010x} \
         (the file is corrupt)"
    )]
    Checksum {
        /// The stored CRC-32.
        stored: u32,
        /// The CRC-32 of the data.
        computed: u32,
    },
    /// A structure code above the largest valid one.
    #[error("node {node}: structure code {code} is out of range (at most {max})")]
    BadStructureCode {
        /// Node index.
        node: u64,
        /// The code found.
        code: u16,
        /// The largest valid code.
        max: u16,
    },
    /// A node that no earlier node claims as a child: not breadth-first.
    #[error(
        "node {node} is not a child of any earlier node (the child counts of nodes 0..{node} \
         account for only {claimed} children): nodes must be in breadth-first order"
    )]
    Orphan {
        /// Node index.
        node: u64,
        /// Number of non-root nodes claimed by nodes before it.
        claimed: u64,
    },
    /// Child counts that claim more nodes than the file holds.
    #[error(
        "node {node} has {count} children, which would end at node {end}, past the {nodes} \
         nodes in the file"
    )]
    ChildOverflow {
        /// Node index.
        node: u64,
        /// Its child count.
        count: u8,
        /// One past its last child.
        end: u64,
        /// Node count from the header.
        nodes: u64,
    },
    /// The header's leaf count disagrees with the nodes.
    #[error("header says {stored} leaves but the nodes have {actual}")]
    LeafCount {
        /// Leaf count from the header.
        stored: u64,
        /// Nodes with no children.
        actual: u64,
    },
    /// An array of the decoded tree could not be allocated: the file's length holds its node
    /// count, but the memory available does not hold the tree. Reported at the node count
    /// (offset 16), which sizes the arrays; [`read`] reports it as [`Error::OutOfMemory`].
    #[error(
        "not enough memory to decode {nodes} nodes ({part}): {gib:.1} GiB",
        gib = *.bytes as f64 / f64::from(1 << 30)
    )]
    OutOfMemory {
        /// Node count from the header.
        nodes: u64,
        /// The array (`"nodes"` or `"sphere codes"`).
        part: &'static str,
        /// How many bytes were asked for.
        bytes: u128,
    },
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "byte {}: {}", self.offset, self.kind)
    }
}

impl std::error::Error for FormatError {}

impl FormatError {
    /// The crate's error for this one: [`Error::OutOfMemory`] naming the nodes of `source` when
    /// the decoder's arrays were refused, else what `otherwise` makes of it.
    pub fn into_error(self, source: &str, otherwise: impl FnOnce(Self) -> Error) -> Error {
        match self.kind {
            FormatErrorKind::OutOfMemory { nodes, part, bytes } => Error::OutOfMemory {
                what: format!("the {nodes} nodes of {source} ({part})"),
                bytes,
            },
            _ => otherwise(self),
        }
    }
}

fn fail<T>(offset: usize, kind: FormatErrorKind) -> Result<T, FormatError> {
    Err(FormatError { offset, kind })
}

// ---------------------------------------------------------------------------------------------
// Public entry points

/// Writes `tree` to `path` as a `.tsplat` file (see [`encode`]).
///
/// # Errors
/// [`Error::OutOfMemory`] from [`encode`] (nothing is written then), or [`Error::Io`].
pub fn write(path: &Path, tree: &SplatTree) -> Result<(), Error> {
    std::fs::write(path, encode(tree)?).map_err(|e| Error::io(path, e))
}

/// Reads a `.tsplat` file. Format errors are [`Error::Parse`] with `line: 0` and a message
/// starting `byte N:`.
///
/// # Errors
/// As [`crate::input::read`]; [`Error::Parse`] for a malformed file;
/// [`Error::OutOfMemory`] naming the file when the decoded tree's arrays cannot be allocated
/// ([`FormatErrorKind::OutOfMemory`]).
pub fn read(path: &Path) -> Result<SplatTree, Error> {
    let bytes = crate::input::read(path)?;
    decode(&bytes).map_err(|e| {
        e.into_error(&path.display().to_string(), |e| Error::Parse {
            path: path.to_path_buf(),
            line: 0,
            message: e.to_string(),
        })
    })
}

/// What an encoding is of, to name it in [`Error::OutOfMemory`].
#[derive(Clone, Copy)]
struct Encoding {
    /// Nodes in the tree.
    nodes: usize,
}

impl Encoding {
    /// Reserves exactly `n` more elements in `v`, or [`Error::OutOfMemory`] naming the
    /// encoding, `part` of it and the bytes asked for.
    fn reserve<T>(self, v: &mut Vec<T>, n: usize, part: &str) -> Result<(), Error> {
        try_reserve_named(v, n, || format!("the .tsplat encoding of {} nodes ({part})", self.nodes))
    }

    /// `n` copies of `value`, or [`Error::OutOfMemory`] as for [`Encoding::reserve`].
    fn filled<T: Clone>(self, n: usize, value: T, part: &str) -> Result<Vec<T>, Error> {
        let mut v = Vec::new();
        self.reserve(&mut v, n, part)?;
        v.resize(n, value);
        Ok(v)
    }
}

/// Encodes a tree: [`HEADER_BYTES`] + [`BYTES_PER_NODE`] per node.
///
/// The nodes are written in breadth-first order from `nodes[0]`, so a tree laid out as
/// [`SplatTree`] documents keeps its node order. Encoding is lossy but conservative: every
/// decoded sphere contains the true sphere of its node and of every node below it (so every
/// point and every leaf splat below), every decoded cone contains the true cone around the
/// decoded normal (up to pi). Time: 9 candidate spheres per node, each checked against the
/// node's subtree, so about `9 n depth` distance evaluations, usually far fewer (a candidate
/// is dropped as soon as it needs more than the best so far), each level's nodes side by side
/// on the current rayon pool (the bytes are the same on any number of threads).
///
/// Never panics, whatever the input: non-finite coordinates are taken as 0, non-finite or
/// negative radii as 0 (such spheres carry no guarantee), a NaN cone as pi, a non-finite normal
/// as zero; child ranges are clipped to the node array, nodes already reached are not visited
/// twice and at most 4 children per node are kept.
///
/// Memory: besides the output, about 130 bytes per node of work arrays (three times the
/// tree's own 40), all allocated before the spheres are encoded.
///
/// # Errors
/// [`Error::SplatExtent`] when the root sphere, which encloses every node's, is not finite
/// in `f32` (points reaching past about 1.7e38 on either side of it), which [`decode`]
/// would refuse;
/// [`Error::OutOfMemory`] when one of its arrays (each proportional to the node count: the
/// breadth-first order, the nodes made safe to quantize, the subtrees' ranges and spheres,
/// the decoded spheres, the output) cannot be allocated, naming the encoding, the array and
/// its bytes: a tree that fits in memory may not leave room to encode it, and an infallible
/// allocation would abort the process instead. (With overcommit the system may still stop
/// the process later; this is what the allocator refuses.)
pub fn encode(tree: &SplatTree) -> Result<Vec<u8>, Error> {
    let encoding = Encoding { nodes: tree.nodes.len() };
    let (order, counts) = breadth_first(encoding, tree)?;
    let n = order.len();
    let mut nodes: Vec<Clean> = Vec::new();
    encoding.reserve(&mut nodes, n, "nodes made safe to quantize")?;
    // In parallel, into the room reserved (an indexed iterator writes in place).
    nodes.par_extend(order.par_iter().map(|&i| Clean::new(&tree.nodes[i])));
    drop(order);

    // First child of each output node (output order is breadth-first by construction).
    let mut first = encoding.filled(n, 0usize, "first children")?;
    let mut next = 1;
    for j in 0..n {
        first[j] = next;
        next += usize::from(counts[j]);
    }

    // Every subtree as a contiguous range of a pre-order array of (centre, radius): subtree
    // sizes bottom-up, then positions top-down.
    let mut size = encoding.filled(n, 1usize, "subtree sizes")?;
    for j in (0..n).rev() {
        for c in first[j]..first[j] + usize::from(counts[j]) {
            size[j] += size[c];
        }
    }
    let mut start = encoding.filled(n, 0usize, "subtree starts")?;
    let mut content = encoding.filled(n, ([0.0f32; 3], 0.0f64), "subtree spheres")?;
    for j in 0..n {
        content[start[j]] = (nodes[j].centre, nodes[j].radius);
        let mut at = start[j] + 1;
        for c in first[j]..first[j] + usize::from(counts[j]) {
            start[c] = at;
            at += size[c];
        }
    }

    let has_normals = nodes.iter().any(|c| c.normal.is_some());
    let has_colors = nodes.iter().any(|c| c.color != [255; 3]);
    let flags = (u32::from(has_normals) * FLAG_NORMALS) | (u32::from(has_colors) * FLAG_COLORS);
    let leaves = counts.iter().filter(|&&c| c == 0).count();

    // No overflow: the tree holds n nodes of 40 bytes each.
    let mut out = Vec::new();
    encoding.reserve(&mut out, HEADER_BYTES + BYTES_PER_NODE * n, "output bytes")?;
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&flags.to_le_bytes());
    out.extend_from_slice(&(n as u64).to_le_bytes());
    out.extend_from_slice(&(leaves as u64).to_le_bytes());

    // Decoded spheres, top-down: each child is quantized against its parent's decoded sphere.
    let zero = Sphere { centre: [0.0; 3], radius: 0.0 };
    let mut decoded = encoding.filled(n, zero, "decoded spheres")?;
    let mut sphere_code = encoding.filled(n, IDENTITY, "sphere codes")?;
    if n > 0 {
        let centre = nodes[0].centre;
        // The largest reach, in parallel (`max` skips NaNs in any order).
        let reach = content.par_iter().map(|&(c, r)| reach(c, r, centre)).reduce(|| 0.0, f64::max);
        decoded[0] = Sphere { centre, radius: round_up_f32(reach) };
    }
    // Level by level (breadth-first, a level's children are the next level), the children
    // side by side: each reads only its parent's decoded sphere, of the level before, so the
    // codes are those of one node after another whatever the thread count. Every level's
    // subtrees together hold about the whole tree, and one node after another this loop
    // was most of the encoding of `trirast pack`'s 15 M points.
    let mut level = 0..n.min(1);
    while !level.is_empty() {
        let last = level.end - 1;
        let children = level.end..first[last] + usize::from(counts[last]);
        let (parents, below) = decoded.split_at_mut(level.end);
        let parents = &*parents;
        let spheres = &mut below[..children.len()];
        let codes = &mut sphere_code[children.clone()];
        // Enough tasks for the threads even for the root's four children.
        let task = (children.len() / 64).clamp(1, 1024);
        let parent_range = &first[level.clone()];
        spheres.par_chunks_mut(task).zip(codes.par_chunks_mut(task)).enumerate().for_each(
            |(k, (spheres, codes))| {
                let c0 = children.start + k * task;
                // The parent of `c0`: the last whose children start at or before it (one
                // without children starts where the next does).
                let mut j = level.start + parent_range.partition_point(|&f| f <= c0) - 1;
                for (i, (sphere, code)) in spheres.iter_mut().zip(codes).enumerate() {
                    let c = c0 + i;
                    while first[j] + usize::from(counts[j]) <= c {
                        j += 1;
                    }
                    let subtree = &content[start[c]..start[c] + size[c]];
                    (*code, *sphere) = encode_sphere(&parents[j], nodes[c].centre, subtree);
                }
            },
        );
        level = children;
    }

    let root = decoded.first().copied().unwrap_or(zero);
    // The decoder refuses such a root: points at +-f32::MAX had been encoded with a radius of
    // inf into a file that could not be read back.
    if !(root.centre.iter().all(|v| v.is_finite()) && root.radius.is_finite()) {
        return Err(Error::SplatExtent { centre: root.centre, radius: root.radius });
    }
    for v in root.centre.into_iter().chain([root.radius]) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&[0; 4]); // checksum, filled in below

    // Each node's six bytes, side by side (the output's room was reserved above).
    debug_assert_eq!(out.len(), HEADER_BYTES, "the header, then the nodes");
    out.resize(HEADER_BYTES + BYTES_PER_NODE * n, 0);
    out[HEADER_BYTES..].par_chunks_mut(BYTES_PER_NODE).enumerate().for_each(|(j, bytes)| {
        let node = &nodes[j];
        let structure = sphere_code[j] * 5 + u16::from(counts[j]);
        let (normal, cone) =
            if has_normals { encode_normal_cone(node.normal, node.cone) } else { ([0; 2], 0) };
        let normal_word = u16::from(normal[0]) | u16::from(normal[1]) << 7 | u16::from(cone) << 14;
        let color = if has_colors { encode_rgb565(node.color) } else { 0 };
        bytes[0..2].copy_from_slice(&structure.to_le_bytes());
        bytes[2..4].copy_from_slice(&normal_word.to_le_bytes());
        bytes[4..6].copy_from_slice(&color.to_le_bytes());
    });

    let crc = file_checksum(&out);
    out[OFFSET_CHECKSUM..OFFSET_CHECKSUM + 4].copy_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// Decodes a `.tsplat` file's bytes.
///
/// Checks, in order: the magic, the version, the header's length, the flags, that the node
/// count matches the length exactly (a count the data cannot hold allocates nothing), the root
/// sphere (finite, radius `>= 0`), the checksum, each node's structure code and that the child
/// counts describe a breadth-first layout, then the leaf count. Allocation is bounded by the
/// input's length (42 bytes per 6-byte node: the nodes and their sphere codes) and made only
/// once the node count has been checked against it; an allocation the allocator refuses is
/// [`FormatErrorKind::OutOfMemory`], not an abort. `first_child` is rebuilt from the
/// breadth-first order (0 for leaves).
///
/// # Errors
/// A [`FormatError`] at the first problem found.
pub fn decode(bytes: &[u8]) -> Result<SplatTree, FormatError> {
    let len = bytes.len();
    let magic_len = len.min(MAGIC.len());
    if let Some(at) = (0..magic_len).find(|&i| bytes[i] != MAGIC[i]) {
        return fail(at, FormatErrorKind::BadMagic);
    }
    if len < MAGIC.len() {
        return fail(len, FormatErrorKind::Truncated { part: "magic", expected: 8 });
    }
    let header = FormatErrorKind::Truncated { part: "header", expected: HEADER_BYTES as u64 };
    if len < OFFSET_VERSION + 4 {
        return fail(len, header);
    }
    let version = le_u32(bytes, OFFSET_VERSION);
    if version != VERSION {
        return fail(OFFSET_VERSION, FormatErrorKind::UnsupportedVersion(version));
    }
    if len < HEADER_BYTES {
        return fail(len, header);
    }
    let flags = le_u32(bytes, OFFSET_FLAGS);
    if flags & !(FLAG_NORMALS | FLAG_COLORS) != 0 {
        return fail(OFFSET_FLAGS, FormatErrorKind::UnknownFlags(flags));
    }
    let count = le_u64(bytes, OFFSET_NODE_COUNT);
    if count > u64::from(u32::MAX) {
        return fail(OFFSET_NODE_COUNT, FormatErrorKind::NodeCountOverflow(count));
    }
    // At most 2^32 - 1 nodes: this cannot overflow u64.
    let expected = HEADER_BYTES as u64 + BYTES_PER_NODE as u64 * count;
    if (len as u64) < expected {
        return fail(len, FormatErrorKind::Truncated { part: "node data", expected });
    }
    if (len as u64) > expected {
        let extra = len as u64 - expected;
        return fail(expected as usize, FormatErrorKind::TrailingBytes { extra, nodes: count });
    }
    // `count` nodes fit in the input, so it fits in usize and bounds every allocation below.
    let n = count as usize;
    let leaves = le_u64(bytes, OFFSET_LEAF_COUNT);
    let root = Sphere {
        centre: [0, 1, 2].map(|a| le_f32(bytes, OFFSET_ROOT + 4 * a)),
        radius: le_f32(bytes, OFFSET_ROOT + 12),
    };
    if n > 0 {
        let bad_centre = root.centre.iter().any(|v| !v.is_finite());
        if bad_centre || !root.radius.is_finite() || root.radius < 0.0 {
            let at = if bad_centre { OFFSET_ROOT } else { OFFSET_ROOT + 12 };
            return fail(
                at,
                FormatErrorKind::BadRoot {
                    centre: format!("{:?}", root.centre),
                    radius: format!("{:?}", root.radius),
                },
            );
        }
    }
    let stored = le_u32(bytes, OFFSET_CHECKSUM);
    let computed = file_checksum(bytes);
    if stored != computed {
        return fail(OFFSET_CHECKSUM, FormatErrorKind::Checksum { stored, computed });
    }

    // Pass 1: fields, structure codes and the breadth-first layout.
    let has_normals = flags & FLAG_NORMALS != 0;
    let has_colors = flags & FLAG_COLORS != 0;
    let mut nodes = Vec::new();
    reserve_decoded(&mut nodes, n, "nodes")?;
    let mut spheres = Vec::new();
    reserve_decoded(&mut spheres, n, "sphere codes")?;
    let mut next: u64 = 1;
    let mut actual_leaves = 0u64;
    for i in 0..n {
        let at = HEADER_BYTES + BYTES_PER_NODE * i;
        let structure = le_u16(bytes, at);
        if structure >= MAX_STRUCTURE_CODE {
            return fail(
                at,
                FormatErrorKind::BadStructureCode {
                    node: i as u64,
                    code: structure,
                    max: MAX_STRUCTURE_CODE - 1,
                },
            );
        }
        let child_count = (structure % 5) as u8;
        let node = i as u64;
        if i > 0 && node >= next {
            return fail(at, FormatErrorKind::Orphan { node, claimed: next - 1 });
        }
        let end = next + u64::from(child_count);
        if end > count {
            return fail(
                at,
                FormatErrorKind::ChildOverflow { node, count: child_count, end, nodes: count },
            );
        }
        let first_child = if child_count == 0 {
            actual_leaves += 1;
            0
        } else {
            next as u32 // < count <= u32::MAX
        };
        next = end;
        let normal_word = le_u16(bytes, at + 2);
        let (normal, cone) = if has_normals {
            let u = (normal_word & 0x7f) as u8;
            let v = (normal_word >> 7 & 0x7f) as u8;
            (decode_normal(u, v), CONE_BUCKETS[usize::from(normal_word >> 14)])
        } else {
            ([0.0; 3], PI)
        };
        let color = if has_colors { decode_rgb565(le_u16(bytes, at + 4)) } else { [255; 3] };
        spheres.push(SPHERES[usize::from(structure / 5)]);
        nodes.push(SplatNode {
            centre: [0.0; 3],
            radius: 0.0,
            normal,
            cone,
            color,
            first_child,
            child_count,
        });
    }
    if actual_leaves != leaves {
        return fail(
            OFFSET_LEAF_COUNT,
            FormatErrorKind::LeafCount { stored: leaves, actual: actual_leaves },
        );
    }

    // Pass 2: spheres, top-down (children always follow their parent).
    if n > 0 {
        nodes[0].centre = root.centre;
        nodes[0].radius = root.radius;
    }
    for i in 0..n {
        let parent = Sphere { centre: nodes[i].centre, radius: nodes[i].radius };
        let first = nodes[i].first_child as usize;
        for c in first..first + usize::from(nodes[i].child_count) {
            let s = child_sphere(&parent, spheres[c]);
            nodes[c].centre = s.centre;
            nodes[c].radius = s.radius;
        }
    }
    Ok(SplatTree::new(nodes))
}

/// Reserves exactly `n` elements in the empty `v` for [`decode`], or
/// [`FormatErrorKind::OutOfMemory`] naming `part`.
fn reserve_decoded<T>(v: &mut Vec<T>, n: usize, part: &'static str) -> Result<(), FormatError> {
    try_reserve_named(v, n, String::new).or_else(|_| {
        let bytes = n as u128 * size_of::<T>() as u128;
        fail(OFFSET_NODE_COUNT, FormatErrorKind::OutOfMemory { nodes: n as u64, part, bytes })
    })
}

// ---------------------------------------------------------------------------------------------
// Tree traversal and input cleaning

/// Output order (input indices, breadth-first from the root) and each output node's kept child
/// count. Children out of range or already reached are skipped; at most 4 are kept.
fn breadth_first(encoding: Encoding, tree: &SplatTree) -> Result<(Vec<usize>, Vec<u8>), Error> {
    let n = tree.nodes.len();
    if n == 0 {
        return Ok((Vec::new(), Vec::new()));
    }
    let mut seen = encoding.filled(n, false, "nodes reached")?;
    // Each node is reached at most once: the order never outgrows `n`.
    let mut order = Vec::new();
    encoding.reserve(&mut order, n, "breadth-first order")?;
    order.push(0);
    let mut counts = Vec::new();
    encoding.reserve(&mut counts, n, "child counts")?;
    seen[0] = true;
    let mut j = 0;
    while j < order.len() {
        let node = &tree.nodes[order[j]];
        let start = (node.first_child as usize).min(n);
        let end = (node.first_child as usize).saturating_add(usize::from(node.child_count)).min(n);
        let mut kept = 0u8;
        for (c, seen) in seen.iter_mut().enumerate().take(end).skip(start) {
            if kept == 4 {
                break;
            }
            if !*seen {
                *seen = true;
                order.push(c);
                kept += 1;
            }
        }
        counts.push(kept);
        j += 1;
    }
    Ok((order, counts))
}

/// A node with its values made safe to quantize.
struct Clean {
    centre: [f32; 3],
    radius: f64,
    /// Unit normal (f64), `None` when zero or not finite.
    normal: Option<[f64; 3]>,
    cone: f64,
    color: [u8; 3],
}

impl Clean {
    fn new(node: &SplatNode) -> Self {
        let centre = node.centre.map(|v| if v.is_finite() { v } else { 0.0 });
        let radius =
            if node.radius.is_finite() && node.radius > 0.0 { f64::from(node.radius) } else { 0.0 };
        let n = node.normal.map(f64::from);
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let normal = (len.is_finite() && len > 0.0).then(|| n.map(|v| v / len));
        let cone = if node.cone.is_nan() {
            std::f64::consts::PI
        } else {
            f64::from(node.cone).clamp(0.0, std::f64::consts::PI)
        };
        Self { centre, radius, normal, cone, color: node.color }
    }
}

fn distance(a: [f32; 3], b: [f32; 3]) -> f64 {
    let d = [0, 1, 2].map(|i| f64::from(a[i]) - f64::from(b[i]));
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// The smallest f32 at least `v` (`f32::MAX` if `v` is larger; `v >= 0`).
fn round_up_f32(v: f64) -> f32 {
    let r = v as f32;
    if r.is_infinite() {
        f32::MAX
    } else if f64::from(r) < v {
        r.next_up()
    } else {
        r
    }
}

// ---------------------------------------------------------------------------------------------
// Spheres: the 16-bit structure code

/// A decoded sphere.
#[derive(Clone, Copy, Debug)]
struct Sphere {
    centre: [f32; 3],
    radius: f32,
}

/// Whether the level tuple (x, y, z in 0..=12, k in 0..=12) is in the alphabet:
/// `2 |q - 6| + k <= 17` with `|.|` Euclidean, in steps of `R / 12`.
const fn in_alphabet(x: i32, y: i32, z: i32, k: i32) -> bool {
    let (dx, dy, dz) = (x - 6, y - 6, z - 6);
    4 * (dx * dx + dy * dy + dz * dz) <= (17 - k) * (17 - k)
}

const fn count_alphabet() -> usize {
    let mut n = 0;
    let mut i = 0;
    while i < 13 * 13 * 13 * 13 {
        let (x, y, z, k) = (i / 2197, i / 169 % 13, i / 13 % 13, i % 13);
        if in_alphabet(x, y, z, k) {
            n += 1;
        }
        i += 1;
    }
    n
}

/// Number of (centre, radius) pairs a child can have.
const SPHERE_CODES: usize = count_alphabet();
/// One past the largest structure code.
const MAX_STRUCTURE_CODE: u16 = (SPHERE_CODES * 5) as u16;
const _: () = assert!(SPHERE_CODES == 11297 && SPHERE_CODES * 5 <= 65536);

/// The alphabet in order (x slowest, then y, z, k), packed `x << 12 | y << 8 | z << 4 | k`.
static SPHERES: [u16; SPHERE_CODES] = {
    let mut table = [0u16; SPHERE_CODES];
    let (mut i, mut n) = (0, 0);
    while i < 13 * 13 * 13 * 13 {
        let (x, y, z, k) = (i / 2197, i / 169 % 13, i / 13 % 13, i % 13);
        if in_alphabet(x, y, z, k) {
            table[n] = (x << 12 | y << 8 | z << 4 | k) as u16;
            n += 1;
        }
        i += 1;
    }
    table
};

/// Code of each level tuple `((x * 13 + y) * 13 + z) * 13 + k`, `u16::MAX` when outside the
/// alphabet.
static SPHERE_INDEX: [u16; 28561] = {
    let mut table = [u16::MAX; 28561];
    let (mut i, mut n) = (0, 0);
    while i < 28561 {
        let (x, y, z, k) = (i / 2197, i / 169 % 13, i / 13 % 13, i % 13);
        if in_alphabet(x, y, z, k) {
            table[i as usize] = n;
            n += 1;
        }
        i += 1;
    }
    table
};

/// The code of "the parent's sphere itself": centre levels 6, radius level 12.
const IDENTITY: u16 = SPHERE_INDEX[((6 * 13 + 6) * 13 + 6) * 13 + 12];

/// Decodes a child's sphere from its packed levels and its parent's decoded sphere. With
/// `s = R / 12` (f32): centre `c + 2 (q - 6) s` per axis, radius `k s`, except that `k = 12`
/// gives `R` exactly (so the identity code reproduces the parent bit for bit).
fn child_sphere(parent: &Sphere, packed: u16) -> Sphere {
    let s = parent.radius / 12.0;
    let level = |shift: u16| i32::from(packed >> shift & 15);
    let q = [level(12), level(8), level(4)];
    let k = level(0);
    let centre = [0, 1, 2].map(|a| parent.centre[a] + (2 * (q[a] - 6)) as f32 * s);
    let radius = if k == 12 { parent.radius } else { k as f32 * s };
    Sphere { centre, radius }
}

/// Chooses a child's code: the decoded sphere with the smallest radius level that contains
/// every sphere of the child's subtree (`subtree`, the child's own first), ties broken by the
/// centre nearer the child's true centre. Candidates: the parent's sphere itself (the identity
/// code) and the 8 combinations of the two centre levels around the child's true centre on
/// each axis, nearest first (trying 4 levels per axis, 64 candidates, shrank decoded radii by
/// under 0.5% on a 50,000-point test tree: not worth 8 times the work).
///
/// The identity is always valid: the parent's decoded sphere contains every sphere of the
/// parent's subtree, so every sphere of the child's. Containment is exact (the largest distance
/// from the decoded centre over the subtree's spheres, see [`reach`]), so nothing is
/// bounded by a bound of a bound and errors do not compound down the tree.
fn encode_sphere(parent: &Sphere, centre: [f32; 3], subtree: &[([f32; 3], f64)]) -> (u16, Sphere) {
    let s = parent.radius / 12.0;
    let identity_dist = distance(centre, parent.centre);
    // (k, distance to the true centre, code, decoded sphere)
    let mut best = (12, identity_dist, IDENTITY, *parent);
    if !(s > 0.0 && s.is_finite()) {
        // A point parent: its children can only be points at its centre.
        let need = subtree.iter().map(|&(c, r)| distance(c, parent.centre) + r).fold(0.0, f64::max);
        if need == 0.0 {
            let index = SPHERE_INDEX[((6 * 13 + 6) * 13 + 6) * 13];
            return (index, Sphere { centre: parent.centre, radius: 0.0 });
        }
        return (best.2, best.3);
    }
    // Per axis: the nearest level, then the one on the other side of the true centre.
    let mut levels = [[6i32; 2]; 3];
    for a in 0..3 {
        let t = (f64::from(centre[a]) - f64::from(parent.centre[a])) / (2.0 * f64::from(s)) + 6.0;
        let t = if t.is_nan() { 6.0 } else { t.clamp(0.0, 12.0) };
        let near = t.round();
        let other = if t >= near { t.ceil() } else { t.floor() };
        levels[a] = [near as i32, other as i32];
    }
    for corner in 0..8 {
        let q = [0, 1, 2].map(|a| levels[a][corner >> a & 1]);
        let flat = ((q[0] * 13 + q[1]) * 13 + q[2]) as usize;
        let at_k = |k: i32| child_sphere(parent, pack(q, k));
        let c_dec = at_k(0).centre;
        // The largest reach over the subtree, given up once it exceeds the best radius so far.
        let limit = f64::from(best.3.radius);
        let mut need = 0.0f64;
        for &(c, r) in subtree {
            need = need.max(reach(c, r, c_dec));
            if need > limit {
                break;
            }
        }
        if need > limit {
            continue;
        }
        let mut k = ((need / f64::from(s)).floor() as i32 - 1).clamp(0, 12);
        while k <= 12 && f64::from(at_k(k).radius) < need {
            k += 1;
        }
        if k > 12 {
            continue;
        }
        let index = SPHERE_INDEX[flat * 13 + k as usize];
        let dist = distance(centre, c_dec);
        if index != u16::MAX && (k, dist) < (best.0, best.1) {
            best = (k, dist, index, at_k(k));
        }
    }
    (best.2, best.3)
}

/// What a decoded sphere centred at `centre` must reach to contain the sphere `(c, r)`: exactly
/// `r` when the centres are equal, else the f64 distance plus `r`, times `1 +` [`MARGIN`].
fn reach(c: [f32; 3], r: f64, centre: [f32; 3]) -> f64 {
    let d = distance(c, centre);
    if d == 0.0 { r } else { (d + r) * (1.0 + MARGIN) }
}

fn pack(q: [i32; 3], k: i32) -> u16 {
    (q[0] << 12 | q[1] << 8 | q[2] << 4 | k) as u16
}

// ---------------------------------------------------------------------------------------------
// Normals, cones, colours

/// Octahedral decoding of the 7-bit levels `u, v` in 0..=126 (each `(u - 63) / 63`, so the
/// axes and the octahedron's vertices are exact); level 127 on either is reserved for "no
/// normal" and decodes to zero.
fn decode_normal(u: u8, v: u8) -> [f32; 3] {
    if u >= NO_NORMAL || v >= NO_NORMAL {
        return [0.0; 3];
    }
    let mut x = f32::from(i16::from(u) - 63) / 63.0;
    let mut y = f32::from(i16::from(v) - 63) / 63.0;
    let z = 1.0 - x.abs() - y.abs();
    if z < 0.0 {
        let (ax, ay) = (x.abs(), y.abs());
        x = (1.0 - ay) * if x >= 0.0 { 1.0 } else { -1.0 };
        y = (1.0 - ax) * if y >= 0.0 { 1.0 } else { -1.0 };
    }
    let len = (x * x + y * y + z * z).sqrt();
    [x / len, y / len, z / len]
}

/// The octahedral levels of unit `n`: of the 4 grid points around its projection, the one whose
/// decoded normal is closest in angle.
fn encode_normal(n: [f64; 3]) -> [u8; 2] {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    let (mut x, mut y) = (n[0] / l1, n[1] / l1);
    if n[2] < 0.0 {
        let (ax, ay) = (x.abs(), y.abs());
        x = (1.0 - ay) * if x >= 0.0 { 1.0 } else { -1.0 };
        y = (1.0 - ax) * if y >= 0.0 { 1.0 } else { -1.0 };
    }
    let fu = ((x + 1.0) * 63.0).clamp(0.0, 126.0);
    let fv = ((y + 1.0) * 63.0).clamp(0.0, 126.0);
    let mut best = ([63u8, 63u8], f64::NEG_INFINITY);
    for u in [fu.floor(), fu.ceil()] {
        for v in [fv.floor(), fv.ceil()] {
            let code = [u as u8, v as u8];
            let d = decode_normal(code[0], code[1]).map(f64::from);
            let dot = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
            if dot > best.1 {
                best = (code, dot);
            }
        }
    }
    best.0
}

/// Angle between two vectors, radians (robust for small angles).
fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    let cross = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let sin = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
    let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    sin.atan2(cos)
}

/// Normal levels and cone bucket. The bucket is the first one at least `cone` plus the angle
/// between the true and the decoded normal, so it bounds every normal the true cone bounds.
/// A zero normal gets the reserved code and the "any direction" bucket.
fn encode_normal_cone(normal: Option<[f64; 3]>, cone: f64) -> ([u8; 2], u8) {
    let Some(n) = normal else {
        return ([NO_NORMAL; 2], 3);
    };
    let code = encode_normal(n);
    let error = angle(n, decode_normal(code[0], code[1]).map(f64::from));
    let need = cone + error;
    let bucket = CONE_BUCKETS.iter().position(|&b| f64::from(b) >= need).unwrap_or(3);
    (code, bucket as u8)
}

/// 8-bit value of a 5- or 6-bit channel: bit replication (`v << 3 | v >> 2` for 5 bits).
const fn expand(v: u32, bits: u32) -> u8 {
    (v << (8 - bits) | v >> (2 * bits - 8)) as u8
}

/// The nearest `bits`-bit level for each 8-bit value (ties to the lower level).
const fn nearest_levels(bits: u32) -> [u8; 256] {
    let mut table = [0u8; 256];
    let mut c = 0;
    while c < 256 {
        let mut best = 0;
        let mut best_err = 256;
        let mut v = 0;
        while v < 1 << bits {
            let e = expand(v, bits) as i32 - c as i32;
            let e = if e < 0 { -e } else { e };
            if e < best_err {
                best_err = e;
                best = v;
            }
            v += 1;
        }
        table[c] = best as u8;
        c += 1;
    }
    table
}

static LEVEL5: [u8; 256] = nearest_levels(5);
static LEVEL6: [u8; 256] = nearest_levels(6);

/// RGB565: red in bits 11..16, green 5..11, blue 0..5.
fn encode_rgb565(c: [u8; 3]) -> u16 {
    u16::from(LEVEL5[usize::from(c[0])]) << 11
        | u16::from(LEVEL6[usize::from(c[1])]) << 5
        | u16::from(LEVEL5[usize::from(c[2])])
}

fn decode_rgb565(v: u16) -> [u8; 3] {
    let v = u32::from(v);
    [expand(v >> 11, 5), expand(v >> 5 & 63, 6), expand(v & 31, 5)]
}

// ---------------------------------------------------------------------------------------------
// Byte helpers and the checksum

fn le_u16(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn le_u64(b: &[u8], at: usize) -> u64 {
    u64::from(le_u32(b, at)) | u64::from(le_u32(b, at + 4)) << 32
}

fn le_f32(b: &[u8], at: usize) -> f32 {
    f32::from_bits(le_u32(b, at))
}

/// CRC-32 (IEEE 802.3 / zlib / PNG: reflected polynomial 0xEDB88320, initial value and final
/// xor 0xFFFFFFFF) of the header's first 48 bytes followed by every byte after the header.
/// `bytes` is at least [`HEADER_BYTES`] long.
fn file_checksum(bytes: &[u8]) -> u32 {
    let state = crc32_update(!0, &bytes[..OFFSET_CHECKSUM]);
    !crc32_update(state, &bytes[HEADER_BYTES..])
}

static CRC_TABLE: [u32; 256] = {
    let mut table = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut bit = 0;
        while bit < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            bit += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
};

fn crc32_update(mut state: u32, data: &[u8]) -> u32 {
    for &b in data {
        state = CRC_TABLE[((state ^ u32::from(b)) & 0xff) as usize] ^ (state >> 8);
    }
    state
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::refusals::refuse_after;
    use crate::splat::PointCloud;

    /// A built tree (chains included) over `n` points of a fixed-seed cloud with normals and
    /// colours, and a few stragglers far from the rest.
    fn built_tree(n: usize) -> SplatTree {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut rand = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        };
        let positions: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                let spread = if i % 100 == 0 { 50.0 } else { 1.0 };
                [0, 1, 2].map(|_| spread * rand())
            })
            .collect();
        let cloud = PointCloud {
            normals: Some(positions.iter().map(|_| [0.0, 0.6, 0.8]).collect()),
            colors: Some((0..n).map(|i| [i as u8, 7, 200]).collect()),
            positions,
            ..PointCloud::default()
        };
        SplatTree::build(&cloud).unwrap()
    }

    /// A cloud reaching +-f32::MAX has no root sphere `f32` holds: encoding it is an error,
    /// where it had written a radius of inf that decoding refuses. Just inside, at half of
    /// `f32::MAX` either way, the root is finite and the file reads back.
    #[test]
    fn roots_beyond_f32_are_refused() {
        let tree = |extent: f32| {
            let positions = vec![[0.0, 0.0, extent], [0.0, 0.0, -extent]];
            SplatTree::build(&PointCloud { positions, ..PointCloud::default() }).unwrap()
        };
        let e = encode(&tree(f32::MAX)).unwrap_err();
        assert!(matches!(e, Error::SplatExtent { radius, .. } if radius.is_infinite()), "{e:?}");
        let bytes = encode(&tree(f32::MAX / 4.0)).unwrap();
        assert!(decode(&bytes).is_ok());
    }

    /// The bytes do not depend on the thread count, though each level's nodes are encoded
    /// side by side: one, two and three threads give the same file for a tree whose levels
    /// are cut into many tasks (the pinned files in `tests/splat_format.rs` hold the bytes to
    /// those of the encoder that took one node after another).
    #[test]
    fn encoding_does_not_depend_on_the_thread_count() {
        let tree = built_tree(20_000);
        let on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| encode(&tree).unwrap())
        };
        let one = on(1);
        assert_eq!(decode(&one).unwrap().nodes.len(), tree.nodes.len());
        assert!(on(2) == one && on(3) == one, "the bytes moved with the thread count");
    }

    /// Each of the encoder's reservations, refused in turn as an allocator refuses a request
    /// too large for it, is an [`Error::OutOfMemory`] naming the encoding, the array and its
    /// bytes, not an abort (`trirast pack` of 15 M points under `ulimit -v` built the
    /// hierarchy, then aborted encoding it). Once none is refused the bytes are the usual ones.
    #[test]
    fn every_refused_encoder_reservation_is_an_error_naming_the_array() {
        let tree = built_tree(600);
        assert!(tree.nodes.iter().any(|n| n.child_count == 1), "no chains");
        let n = tree.nodes.len();
        let bytes = |size: usize| (n * size) as u128;
        let all = [
            ("nodes reached", bytes(1)),
            ("breadth-first order", bytes(8)),
            ("child counts", bytes(1)),
            ("nodes made safe to quantize", bytes(size_of::<Clean>())),
            ("first children", bytes(8)),
            ("subtree sizes", bytes(8)),
            ("subtree starts", bytes(8)),
            ("subtree spheres", bytes(24)),
            ("output bytes", (HEADER_BYTES + BYTES_PER_NODE * n) as u128),
            ("decoded spheres", bytes(16)),
            ("sphere codes", bytes(2)),
        ];
        check_refusals(&tree, &all);
        // The empty tree allocates its header only.
        check_refusals(&SplatTree::default(), &[("output bytes", HEADER_BYTES as u128)]);
    }

    /// Refuses each of `encode(tree)`'s reservations in turn: the `k`-th refusal must be the
    /// error `parts[k]` describes, and with none refused the bytes must be `encode`'s.
    fn check_refusals(tree: &SplatTree, parts: &[(&str, u128)]) {
        let whole = encode(tree).unwrap();
        let prefix = format!("the .tsplat encoding of {} nodes (", tree.nodes.len());
        for k in 0.. {
            refuse_after(Some(k));
            let encoded = encode(tree);
            refuse_after(None);
            match encoded {
                Ok(bytes) => {
                    assert_eq!(k, parts.len(), "allocations refused");
                    assert!(bytes == whole, "refusing allocation {k} and after");
                    return;
                }
                Err(Error::OutOfMemory { what, bytes }) => {
                    let part = what.strip_prefix(&prefix).and_then(|w| w.strip_suffix(')'));
                    assert!(k < parts.len(), "allocation {k}: {what}");
                    assert_eq!((part, bytes), (Some(parts[k].0), parts[k].1), "allocation {k}");
                }
                Err(e) => panic!("allocation {k}: {e}"),
            }
        }
    }

    /// The decoder's two arrays, refused in turn: [`FormatErrorKind::OutOfMemory`] at the node
    /// count, and through [`read`] an [`Error::OutOfMemory`] naming the file.
    #[test]
    fn every_refused_decoder_reservation_is_an_error() {
        let tree = built_tree(300);
        let bytes = encode(&tree).unwrap();
        let n = tree.nodes.len();
        let nodes = n as u64;
        let want = decode(&bytes).unwrap();
        let path = std::env::temp_dir().join(format!("trirast-oom-{}.tsplat", std::process::id()));
        std::fs::write(&path, &bytes).unwrap();
        for (k, part, size) in [(0, "nodes", size_of::<SplatNode>()), (1, "sphere codes", 2)] {
            let asked = (n * size) as u128;
            refuse_after(Some(k));
            let e = decode(&bytes).unwrap_err();
            refuse_after(None);
            let kind = FormatErrorKind::OutOfMemory { nodes, part, bytes: asked };
            assert_eq!(e, FormatError { offset: OFFSET_NODE_COUNT, kind });
            let text = format!("byte 16: not enough memory to decode {n} nodes ({part}): 0.0 GiB");
            assert_eq!(e.to_string(), text);

            refuse_after(Some(k));
            let read = read(&path);
            refuse_after(None);
            match read {
                Err(Error::OutOfMemory { what, bytes }) => {
                    assert_eq!(what, format!("the {n} nodes of {} ({part})", path.display()));
                    assert_eq!(bytes, asked);
                }
                other => panic!("{other:?}"),
            }
        }
        refuse_after(Some(2));
        let decoded = decode(&bytes);
        refuse_after(None);
        assert_eq!(decoded.unwrap(), want);
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(!crc32_update(!0, b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn sphere_alphabet_is_consistent() {
        assert_eq!(SPHERE_CODES, 11297);
        assert_eq!(MAX_STRUCTURE_CODE, 56485);
        for (index, &packed) in SPHERES.iter().enumerate() {
            let l = |s: u16| usize::from(packed >> s & 15);
            let flat = ((l(12) * 13 + l(8)) * 13 + l(4)) * 13 + l(0);
            assert_eq!(usize::from(SPHERE_INDEX[flat]), index);
        }
        assert_eq!(SPHERE_INDEX.iter().filter(|&&i| i != u16::MAX).count(), SPHERE_CODES);
        assert_eq!(SPHERES[usize::from(IDENTITY)], 0x666c);
        // The identity reproduces the parent bit for bit.
        let p = Sphere { centre: [1.5, -2.25, 1e7], radius: 0.3 };
        let s = child_sphere(&p, SPHERES[usize::from(IDENTITY)]);
        assert_eq!((s.centre, s.radius.to_bits()), (p.centre, p.radius.to_bits()));
    }

    #[test]
    fn colour_quantization_is_nearest_and_within_bounds() {
        let mut worst = [0i32; 3];
        for c in 0..=255u8 {
            let d = decode_rgb565(encode_rgb565([c, c, c]));
            for ch in 0..3 {
                worst[ch] = worst[ch].max((i32::from(d[ch]) - i32::from(c)).abs());
            }
        }
        assert_eq!(worst, [4, 2, 4]);
        for v in 0..=u16::MAX {
            assert_eq!(encode_rgb565(decode_rgb565(v)), v, "{v:#x}");
        }
    }

    #[test]
    fn normal_quantization_error_and_reserved_code() {
        assert_eq!(decode_normal(127, 127), [0.0; 3]);
        assert_eq!(decode_normal(127, 5), [0.0; 3]);
        for (n, code) in [
            ([0.0, 0.0, 1.0], [63, 63]),
            ([1.0, 0.0, 0.0], [126, 63]),
            ([0.0, -1.0, 0.0], [63, 0]),
            ([0.0, 0.0, -1.0], [126, 126]),
        ] {
            assert_eq!(encode_normal(n), code);
            assert_eq!(decode_normal(code[0], code[1]).map(f64::from), n);
        }
        assert_eq!(decode_normal(0, 0), [0.0, 0.0, -1.0]);
        let mut worst: f64 = 0.0;
        let steps = 400;
        for i in 0..=steps {
            let theta = std::f64::consts::PI * f64::from(i) / f64::from(steps);
            for j in 0..2 * steps {
                let phi = std::f64::consts::PI * f64::from(j) / f64::from(steps);
                let n = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
                let code = encode_normal(n);
                assert!(code[0] < NO_NORMAL && code[1] < NO_NORMAL);
                worst = worst.max(angle(n, decode_normal(code[0], code[1]).map(f64::from)));
            }
        }
        eprintln!("worst normal error {} deg", worst.to_degrees());
        assert!(worst.to_degrees() < 1.5, "{}", worst.to_degrees());
        assert!(worst < f64::from(CONE_BUCKETS[0]));
    }

    #[test]
    fn cone_rounds_up() {
        // An axis is exact: a cone that fits a bucket stays in it.
        let n = Some([0.0, 0.0, 1.0]);
        assert_eq!(encode_normal_cone(n, 0.0).1, 0);
        assert_eq!(encode_normal_cone(n, f64::from(CONE_BUCKETS[0])).1, 0);
        assert_eq!(encode_normal_cone(n, f64::from(CONE_BUCKETS[0]) + 1e-9).1, 1);
        // Otherwise the normal's error is added.
        let t = 0.3f64;
        let tilted = Some([t.sin(), 0.0, t.cos()]);
        assert_eq!(encode_normal_cone(tilted, f64::from(CONE_BUCKETS[0])).1, 1);
        assert_eq!(encode_normal_cone(n, 0.5).1, 2);
        assert_eq!(encode_normal_cone(n, 1.0).1, 3);
        assert_eq!(encode_normal_cone(None, 0.0), ([NO_NORMAL; 2], 3));
    }

    #[test]
    fn child_sphere_encoding_contains_the_child() {
        let parent = Sphere { centre: [0.5, -1.0, 2.0], radius: 1.25 };
        let mut state = 0x1234_5678_u64;
        let mut rand = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..20_000 {
            // A random sphere inside the parent.
            let r = f64::from(parent.radius) * rand();
            let room = f64::from(parent.radius) - r;
            let dir = [rand() - 0.5, rand() - 0.5, rand() - 0.5];
            let len = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt().max(1e-9);
            let d = room * rand().cbrt();
            let c = [0, 1, 2].map(|a| (f64::from(parent.centre[a]) + dir[a] / len * d) as f32);
            let (code, s) = encode_sphere(&parent, c, &[(c, r)]);
            let again = child_sphere(&parent, SPHERES[usize::from(code)]);
            assert_eq!((again.centre, again.radius), (s.centre, s.radius));
            assert!(distance(c, s.centre) + r <= f64::from(s.radius));
        }
    }
}
