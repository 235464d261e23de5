//! STL reader: ASCII and binary.
//!
//! Hand-written rather than taken from `stl_io`, whose reader cannot meet this crate's error
//! contract: its ASCII errors carry no line number (and it drops blank lines before parsing, so
//! one cannot be recovered), its binary reader trusts the header's triangle count, and it
//! decides ASCII vs binary by the `solid ` prefix alone, so binary files whose 80-byte header
//! starts with `solid` (common) are misread as ASCII. Both formats are simple enough that a
//! focused reader is shorter than the workarounds.
//!
//! Format detection: a file whose first word is `solid` is ASCII unless its size is exactly
//! `84 + 50 * count` for the little-endian triangle count at byte 80, in which case it is a
//! binary file with a text-like header. Anything else is binary, and a size that disagrees with
//! the count is an error naming byte 80.
//!
//! ASCII: keywords are matched case-insensitively; a file may hold several `solid ... endsolid`
//! blocks; `facet normal nx ny nz` may omit the normal; an `outer loop` of more than three
//! vertices is accepted as a polygon and triangulated by [`crate::polygon::triangulate_face`].
//!
//! **Welding.** STL stores every facet's corners separately, with a per-facet normal. The
//! [`Mesh`] produced here welds them: corners at bit-identical positions (after folding `-0.0`
//! into `0.0`) share one vertex, and `normals` is `None`. Welding restores the connectivity the
//! format throws away, which the pipeline needs to compute smooth vertex normals, and costs
//! nothing for flat shading, since the pipeline recomputes each facet normal from the positions
//! (the stored ones are often zero or inaccurate, and would only agree with the winding by
//! convention). A model that wants hard edges gets them from the pipeline's flat shading or a
//! crease angle, not from unwelded corners. Triangles keep the file's order and winding;
//! degenerate facets are kept (setup rejects zero-area triangles).
//!
//! Binary errors are [`Error::Parse`] with `line: 0` and a message starting `byte N:`.

use std::collections::HashMap;
use std::path::Path;

use super::Mesh;
use crate::error::Error;

/// Reads an STL file (ASCII or binary) as a welded [`Mesh`].
pub fn read(path: &Path) -> Result<Mesh, Error> {
    let bytes = crate::input::read(path)?;
    parse(&bytes, path)
}

/// Parses the contents of an STL file; `path` is only used to name the file in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, Error> {
    let fail = |at: At, message: String| match at {
        At::Line(line) => Error::Parse { path: path.to_path_buf(), line, message },
        At::Byte(offset) => Error::Parse {
            path: path.to_path_buf(),
            line: 0,
            message: format!("byte {offset}: {message}"),
        },
    };
    let binary_size = binary_size(bytes);
    let starts_with_solid = first_word(bytes).eq_ignore_ascii_case(b"solid");
    if starts_with_solid && binary_size != Some(bytes.len() as u64) {
        return parse_ascii(bytes).map_err(|(line, message)| {
            // A binary file whose header starts with `solid` but whose size is wrong: the
            // size is the more useful complaint.
            if looks_binary(bytes)
                && let Err((at, message)) = check_binary_size(bytes)
            {
                return fail(
                    at,
                    format!("{message} (it starts with `solid` but is not ASCII STL either)"),
                );
            }
            fail(At::Line(line), message)
        });
    }
    parse_binary(bytes).map_err(|(at, message)| fail(at, message))
}

#[derive(Clone, Copy, Debug)]
enum At {
    Line(usize),
    Byte(u64),
}

/// The size a binary STL with this header's triangle count has.
fn binary_size(bytes: &[u8]) -> Option<u64> {
    let count = bytes.get(80..84)?;
    let count = u32::from_le_bytes([count[0], count[1], count[2], count[3]]);
    Some(84 + 50 * u64::from(count))
}

fn first_word(bytes: &[u8]) -> &[u8] {
    let start = bytes.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(bytes.len());
    let rest = &bytes[start..];
    let end = rest.iter().position(u8::is_ascii_whitespace).unwrap_or(rest.len());
    &rest[..end]
}

/// Whether the start of the file has bytes no ASCII STL contains.
fn looks_binary(bytes: &[u8]) -> bool {
    bytes.iter().take(512).any(|&b| b == 0 || (b < 0x20 && !b.is_ascii_whitespace()) || b > 0x7e)
}

fn check_binary_size(bytes: &[u8]) -> Result<u32, (At, String)> {
    let len = bytes.len() as u64;
    let Some(expected) = binary_size(bytes) else {
        return Err((
            At::Byte(len),
            format!(
                "file ends after {len} bytes: a binary STL starts with an 80-byte header and a \
                 4-byte triangle count"
            ),
        ));
    };
    let count = (expected - 84) / 50;
    if expected != len {
        return Err((
            At::Byte(80),
            format!(
                "the header declares {count} triangles, which take {expected} bytes (84 + 50 per \
                 triangle), but the file has {len} bytes"
            ),
        ));
    }
    Ok(count as u32)
}

/// Welds corners into shared vertices.
#[derive(Default)]
struct Welder {
    mesh: Mesh,
    index: HashMap<[u32; 3], u32>,
}

impl Welder {
    fn vertex(&mut self, p: [f32; 3]) -> u32 {
        // `+ 0.0` folds -0.0 into 0.0; positions are finite, so bits identify them.
        let p = p.map(|c| c + 0.0);
        let next = self.mesh.positions.len() as u32;
        let positions = &mut self.mesh.positions;
        *self.index.entry(p.map(f32::to_bits)).or_insert_with(|| {
            positions.push(p);
            next
        })
    }
}

fn parse_binary(bytes: &[u8]) -> Result<Mesh, (At, String)> {
    let count = check_binary_size(bytes)?;
    let mut welder = Welder::default();
    welder.mesh.triangles.reserve(count as usize);
    welder.mesh.polygon_count = count as usize;
    for (i, facet) in bytes[84..].chunks_exact(50).enumerate() {
        let mut triangle = [0; 3];
        for (k, v) in triangle.iter_mut().enumerate() {
            let mut p = [0.0f32; 3];
            for (c, out) in p.iter_mut().enumerate() {
                let at = 12 + 12 * k + 4 * c;
                *out = f32::from_le_bytes([facet[at], facet[at + 1], facet[at + 2], facet[at + 3]]);
                if !out.is_finite() {
                    let offset = 84 + 50 * i as u64 + at as u64;
                    return Err((
                        At::Byte(offset),
                        format!(
                            "triangle {i}, vertex {k}: coordinate {} is {out}, expected a finite \
                             number",
                            ["x", "y", "z"][c]
                        ),
                    ));
                }
            }
            *v = welder.vertex(p);
        }
        welder.mesh.triangles.push(triangle);
    }
    Ok(welder.mesh)
}

/// An ASCII error: 1-based line and message.
type Fail = (usize, String);

/// A non-blank line: its number and its tokens.
type Tokens<'a> = (usize, Vec<&'a str>);

/// Lines of an ASCII STL as (1-based line, tokens), skipping blank lines.
struct Lines<'a> {
    inner: std::slice::Split<'a, u8, fn(&u8) -> bool>,
    /// The last line number seen (for end-of-file errors).
    last: usize,
}

impl<'a> Lines<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        let newline: fn(&u8) -> bool = |&b| b == b'\n';
        Self { inner: bytes.split(newline), last: 0 }
    }

    /// The next non-blank line, or `None` at the end of the file.
    fn next(&mut self) -> Result<Option<Tokens<'a>>, Fail> {
        for raw in self.inner.by_ref() {
            self.last += 1;
            let line = self.last;
            let text =
                std::str::from_utf8(raw).map_err(|_| (line, "not valid UTF-8".to_string()))?;
            let tokens: Vec<&str> = text.split_ascii_whitespace().collect();
            if !tokens.is_empty() {
                return Ok(Some((line, tokens)));
            }
        }
        Ok(None)
    }

    /// The next non-blank line, where `what` is expected.
    fn require(&mut self, what: &str) -> Result<Tokens<'a>, Fail> {
        self.next()?.ok_or_else(|| (self.last, format!("file ends where {what} was expected")))
    }

    /// The next line, which must start with `keyword`.
    fn expect(&mut self, keyword: &str, what: &str) -> Result<Tokens<'a>, Fail> {
        let (line, tokens) = self.require(what)?;
        if !tokens[0].eq_ignore_ascii_case(keyword) {
            return Err((line, format!("expected {what}, found `{}`", tokens.join(" "))));
        }
        Ok((line, tokens))
    }
}

fn numbers(tokens: &[&str], line: usize, what: &str) -> Result<[f32; 3], Fail> {
    if tokens.len() != 3 {
        return Err((line, format!("`{what}` takes 3 numbers, found {}", tokens.len())));
    }
    let mut out = [0.0; 3];
    for (o, t) in out.iter_mut().zip(tokens) {
        *o = t.parse().map_err(|_| (line, format!("expected a number, found `{t}`")))?;
    }
    Ok(out)
}

fn parse_ascii(bytes: &[u8]) -> Result<Mesh, Fail> {
    let mut lines = Lines::new(bytes);
    let mut welder = Welder::default();
    let mut corners = Vec::new();
    let mut points = Vec::new();
    lines.expect("solid", "`solid`")?;
    loop {
        let (line, tokens) = lines.require("`facet` or `endsolid`")?;
        let keyword = tokens[0];
        if keyword.eq_ignore_ascii_case("endsolid") {
            match lines.next()? {
                None => break,
                Some((_, t)) if t[0].eq_ignore_ascii_case("solid") => continue,
                Some((line, t)) => {
                    return Err((
                        line,
                        format!("expected `solid` or the end of the file, found `{}`", t.join(" ")),
                    ));
                }
            }
        }
        if !keyword.eq_ignore_ascii_case("facet") {
            return Err((
                line,
                format!(
                    "expected `facet normal nx ny nz` or `endsolid`, found `{}`",
                    tokens.join(" ")
                ),
            ));
        }
        if tokens.len() > 1 {
            if !tokens[1].eq_ignore_ascii_case("normal") {
                return Err((
                    line,
                    format!("expected `facet normal nx ny nz`, found `{}`", tokens.join(" ")),
                ));
            }
            // The normal is checked for syntax but not kept (see the module documentation).
            numbers(&tokens[2..], line, "facet normal")?;
        }
        let (line, tokens) = lines.expect("outer", "`outer loop`")?;
        if tokens.len() != 2 || !tokens[1].eq_ignore_ascii_case("loop") {
            return Err((line, format!("expected `outer loop`, found `{}`", tokens.join(" "))));
        }
        corners.clear();
        points.clear();
        loop {
            let (line, tokens) = lines.require("`vertex x y z` or `endloop`")?;
            if tokens[0].eq_ignore_ascii_case("endloop") {
                if points.len() < 3 {
                    return Err((
                        line,
                        format!("a facet needs 3 or more vertices, found {}", points.len()),
                    ));
                }
                break;
            }
            if !tokens[0].eq_ignore_ascii_case("vertex") {
                return Err((
                    line,
                    format!("expected `vertex x y z` or `endloop`, found `{}`", tokens.join(" ")),
                ));
            }
            let p = numbers(&tokens[1..], line, "vertex")?;
            if !p.iter().all(|c| c.is_finite()) {
                return Err((line, format!("vertex {p:?} is not finite")));
            }
            points.push(p);
            corners.push(welder.vertex(p));
        }
        lines.expect("endfacet", "`endfacet`")?;
        welder.mesh.polygon_count += 1;
        if corners.len() == 3 {
            welder.mesh.triangles.push([corners[0], corners[1], corners[2]]);
        } else {
            for t in crate::polygon::triangulate_face(&points) {
                if let (Some(&a), Some(&b), Some(&c)) =
                    (corners.get(t[0]), corners.get(t[1]), corners.get(t[2]))
                {
                    welder.mesh.triangles.push([a, b, c]);
                }
            }
        }
    }
    Ok(welder.mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    const CUBE_CORNER: &str = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n\
        vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n\
        facet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 -0\nendloop\n\
        endfacet\nendsolid t\n";

    #[test]
    fn ascii_welds_shared_corners() {
        let m = parse(CUBE_CORNER.as_bytes(), Path::new("t.stl")).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [1, 3, 2]]);
        assert_eq!(m.polygon_count, 2);
        assert!(m.normals.is_none());
    }

    #[test]
    fn binary_with_solid_header_is_binary() {
        let mut b = b"solid binary".to_vec();
        b.resize(80, b' ');
        b.extend_from_slice(&1u32.to_le_bytes());
        for v in [[0.0f32; 3], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            for c in v {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
        let m = parse(&b, Path::new("t.stl")).unwrap();
        assert_eq!(m.triangles.len(), 1);
        b.push(0);
        let e = parse(&b, Path::new("t.stl")).unwrap_err().to_string();
        assert!(e.starts_with("t.stl: byte 80: the header declares 1 triangles"), "{e}");
        assert!(e.contains("not ASCII STL either"), "{e}");
    }

    #[test]
    fn ascii_errors_name_the_line() {
        let cases: &[(&str, &str)] = &[
            ("solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n", "4: `vertex` takes 3"),
            (
                "solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendloop\n",
                "5: a facet needs 3",
            ),
            ("solid\nfacet normal 0 0 1\nouter loop\n\n", "5: file ends where `vertex"),
            (
                "solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 q\n",
                "4: expected a number, found `q`",
            ),
            (
                "solid x\nfacet\n outer loop\n vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n\
                 endloop\nendsolid\n",
                "8: expected `endfacet`",
            ),
            ("solid x\nendsolid x\njunk\n", "3: expected `solid` or the end"),
            ("solid x\nloop\n", "2: expected `facet normal"),
        ];
        for (src, needle) in cases {
            let e = parse(src.as_bytes(), Path::new("t.stl")).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("t.stl:{needle}")),
                "{e:?} should start with {needle:?}"
            );
        }
    }
}
