//! Deterministic mutation fuzzing of the OBJ reader on stable Rust.
//!
//! Valid seed files are mutated (bit flips, byte and token insertions, deletions, truncations,
//! line duplication, splices between seeds) with a fixed-seed xorshift generator, and every
//! result must satisfy the reader's contract (`common/obj_contract.rs`, which the cargo-fuzz
//! target checks too).
//!
//! `TRIRAST_FUZZ_ITERS` and `TRIRAST_FUZZ_SEED` override the iteration count and the seed for a
//! longer local run; a failure prints the offending input as an escaped byte string.

mod common;
#[path = "common/obj_contract.rs"]
mod obj_contract;

use std::panic::{AssertUnwindSafe, catch_unwind};

use common::xorshift::XorShift;
use obj_contract::check;
use trirast::mesh::obj;

const DEFAULT_ITERS: usize = 20_000;
const DEFAULT_SEED: u64 = 0x0b1e_c7f0_2257_a11d;

const SEEDS: &[&[u8]] = &[
    // Every corner form, negative indices, comments, skipped statements.
    b"# a cube corner\nmtllib x.mtl\no thing\nv 0 0 0\nv 1 0 0 1 0 0\nv 0 1 0\nv 1 1 0.5 1.0\n\
      vt 0 0\nvt 1 0 0\nvt 0.5\nvn 0 0 1\nvn 0 1 0\ng group\nusemtl m\ns off\n\
      f 1 2 3\nf 1/1 2/2 3/3\nf 1//1 2//2 3//1\nf -4/-3/-2 -3/-2/-1 -2/-1/-1 # tail\n\
      f 1 2 4 3\nl 1 2\np 3\n",
    // Window-space quads with colours, CRLF line endings, tabs and trailing blanks.
    b"v 4 4 0.25 1 0 0\r\nv 28 4 0.25 0 1 0\r\nv 28 20 0.25 0 0 1\r\nv 4 20 0.25\r\n\
      f 1 2 3\r\nf\t1 3 4  \r\n\r\nv 36 24 0.5\nv 60 24 0.5\nv 60 44 0.5\nv 36 44 0.5\n\
      f 5 6 7 8\n",
    // Forward references (indices past the vertices read so far, resolved at the end), a pentagon
    // and exponents.
    b"f 1 2 3\nf 3 4 5 1 2\nv 1e1 2.5E0 -0.0\nv 1.5 +3 0\nv -1 -2 1e-3\nv 9 9 9\nv 3 3 3\n",
    // A larger fan with w values and relative indices only.
    b"v 8 8 0.1 2\nv 12 8 0.2 0.5\nv 14 12 0.3 0.25\nv 12 15 0.4 1\nv 8 15 0.5 3\n\
      f -5 -4 -3\nf -5 -3 -2\nf -5 -2 -1\nvt 1 1\nvn 1 0 0\nf -5/-1/-1 -4/-1/-1 -3/-1/-1\n",
];

/// Fragments that steer mutations towards the reader's corner cases.
const TOKENS: &[&[u8]] = &[
    b"v ",
    b"vt ",
    b"vn ",
    b"f ",
    b"/",
    b"//",
    b"#",
    b"\n",
    b"\r\n",
    b" ",
    b"\t",
    b"0",
    b"-0",
    b"1",
    b"-1",
    b"-2",
    b"3",
    b"nan",
    b"NaN",
    b"inf",
    b"-inf",
    b"1e39",
    b"-1e-45",
    b"4294967295",
    b"4294967296",
    b"-4294967297",
    b"9223372036854775807",
    b"-9223372036854775808",
    b"99999999999999999999",
    b"40000",
    b"-32768",
    b"32767.999",
    b"0.5",
    b"1 0 0",
    b"\xff",
    b"\xc3\xa9",
    b"\xe2\x82",
    b"\0",
    b"usemtl a\n",
    b"usemtl b\n",
    b"mtllib none.mtl\n",
];

fn mutate(rng: &mut XorShift, input: &[u8]) -> Vec<u8> {
    let mut data = input.to_vec();
    let ops = 1 + rng.below(4);
    for _ in 0..ops {
        let len = data.len();
        match rng.below(10) {
            // Flip one bit.
            0 if len > 0 => {
                let i = rng.below(len);
                data[i] ^= 1 << rng.below(8);
            }
            // Overwrite a byte with a random one or a structural one.
            1 if len > 0 => {
                let i = rng.below(len);
                data[i] = if rng.below(2) == 0 {
                    rng.next() as u8
                } else {
                    *rng.pick(b" /\n#-0123456789.efv")
                };
            }
            // Insert a token.
            2 | 3 => {
                let at = rng.below(len + 1);
                let token = rng.pick(TOKENS);
                data.splice(at..at, token.iter().copied());
            }
            // Delete a short range.
            4 if len > 0 => {
                let start = rng.below(len);
                let end = (start + 1 + rng.below(8)).min(len);
                data.drain(start..end);
            }
            // Truncate.
            5 => data.truncate(rng.below(len + 1)),
            // Duplicate a line somewhere else.
            6 => {
                let lines: Vec<&[u8]> = data.split(|&b| b == b'\n').collect();
                let mut line = rng.pick(&lines).to_vec();
                line.push(b'\n');
                let at = rng.below(len + 1);
                data.splice(at..at, line);
            }
            // Splice a chunk of another seed in.
            7 => {
                let other = rng.pick(SEEDS);
                let start = rng.below(other.len());
                let end = (start + 1 + rng.below(40)).min(other.len());
                let at = rng.below(len + 1);
                data.splice(at..at, other[start..end].iter().copied());
            }
            // Replace a number-ish byte run with a token (out-of-range indices and values).
            8 if len > 0 => {
                let start = rng.below(len);
                let end = data[start..]
                    .iter()
                    .position(|b| b.is_ascii_whitespace() || *b == b'/')
                    .map_or(len, |k| start + k);
                let token = rng.pick(TOKENS);
                data.splice(start..end, token.iter().copied());
            }
            // Swap two bytes.
            _ if len > 1 => {
                let (i, j) = (rng.below(len), rng.below(len));
                data.swap(i, j);
            }
            _ => {}
        }
    }
    data
}

/// Runs `check` on `input`, turning a panic into an error carrying the input.
fn run_case(input: &[u8]) -> Result<bool, String> {
    catch_unwind(AssertUnwindSafe(|| check(input))).map_err(|e| {
        let what = e
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| e.downcast_ref::<&str>().map(|s| (*s).to_string()))
            .unwrap_or_default();
        format!("{what}\n  input: b\"{}\"", input.escape_ascii())
    })
}

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

#[test]
fn seeds_parse_and_draw() {
    for (i, seed) in SEEDS.iter().enumerate() {
        let mesh = obj::parse(seed).unwrap_or_else(|e| panic!("seed {i} must parse: {e:?}"));
        assert!(mesh.face_count() > 0, "seed {i} has faces");
        run_case(seed).unwrap_or_else(|e| panic!("seed {i}: {e}"));
    }
}

#[test]
fn hand_picked_edge_cases_keep_the_contract() {
    let cases: &[&[u8]] = &[
        b"",
        b"\n",
        b"\n\n\n",
        b"#",
        b"\xff",
        b"v",
        b"f",
        b"f 1 1 1",
        b"f -1 -1 -1",
        b"v 0 0 0\nf 1 1 1",
        b"v 0 0 0\nf -9223372036854775808 1 1",
        b"v 0 0 0\nf 9223372036854775807 1 1",
        b"v 0 0 0\nf 4294967296 1 1",
        b"v 0 0 0\nf 4294967295 1 1",
        b"v 0 0 0\nf 99999999999999999999 1 1",
        b"v 0 0 0\nf 1/ 1/ 1/",
        b"v 0 0 0\nf 1// 1// 1//",
        b"v 0 0 0\nf 1/-1 1 1",
        b"v 0 0 0\nf +1 1 1",
        b"v 0 0 0\nf 1 1 1 1 1 1 1 1 1 1",
        b"v nan nan nan\nv inf -inf 0\nv 1e39 0 0\nf 1 2 3",
        b"v 0 0 0 nan\nv 0 0 0 1e-45\nv 0 0 0 -0\nf 1 2 3",
        b"v 0 0 0 -0.0",
        b"v 0 0 0 1e-46",
        b"v 40000 0 0\nv 0 0 0\nv 0 1 0\nf 1 2 3",
        b"v -32768 -32768 0\nv 32767.99 -32768 0\nv -32768 32767.99 0\nf 1 2 3",
        b"v 0 0 0 nan nan nan\nv 1 0 0 -5 9 inf\nv 0 1 0 0 0 0\nf 1 2 3",
        b"vt\nvn\n",
        b"v 0 0 0\r",
        b"v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3",
        b"\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3",
    ];
    let failures: Vec<String> = cases.iter().filter_map(|c| run_case(c).err()).collect();
    assert!(failures.is_empty(), "{} failures:\n{}", failures.len(), failures.join("\n"));
}

/// Regression: the largest index that fits in `u32` once made the past-the-end message
/// overflow (`max + 1` on `u32::MAX`), a panic in debug builds and "index 0" in release.
#[test]
fn index_two_to_the_32_past_the_end_is_an_error_naming_it() {
    for (src, what) in [
        (&b"v 0 0 0\nf 1 1 4294967296\n"[..], "`v`"),
        (b"v 0 0 0\nvt 0 0\nf 1/4294967296 1/1 1/1\n", "`vt`"),
        (b"v 0 0 0\nvn 0 0 1\nf 1//1 1//1 1//4294967296\n", "`vn`"),
    ] {
        let result = catch_unwind(|| obj::parse(src));
        let (line, message) = result
            .unwrap_or_else(|_| panic!("parse panicked on b\"{}\"", src.escape_ascii()))
            .expect_err("index past the end must be rejected");
        assert_eq!(line, src.split(|&b| b == b'\n').count() - 1);
        assert!(message.contains("4294967296"), "{message}");
        assert!(message.contains(what), "{message}");
    }
}

#[test]
fn mutated_obj_files_never_break_the_reader() {
    let iters = env_or("TRIRAST_FUZZ_ITERS", DEFAULT_ITERS);
    let seed = env_or("TRIRAST_FUZZ_SEED", DEFAULT_SEED);
    let mut rng = XorShift::new(seed);
    let mut failures = Vec::new();
    let (mut accepted, mut rejected) = (0usize, 0usize);
    let mut corpus: Vec<Vec<u8>> = SEEDS.iter().map(|s| s.to_vec()).collect();
    for i in 0..iters {
        let base = rng.pick(&corpus).clone();
        let input = mutate(&mut rng, &base);
        match run_case(&input) {
            Ok(true) => {
                accepted += 1;
                // Keep some accepted inputs as bases for further mutation.
                if corpus.len() < 256 && rng.below(8) == 0 {
                    corpus.push(input);
                }
            }
            Ok(false) => rejected += 1,
            Err(e) => failures.push(format!("iteration {i}: {e}")),
        }
        if failures.len() >= 10 {
            break;
        }
    }
    eprintln!("obj fuzz: {accepted} accepted, {rejected} rejected, seed {seed:#x}");
    assert!(failures.is_empty(), "{} failures:\n{}", failures.len(), failures.join("\n"));
    // The mutations must exercise both outcomes, or the test proves little.
    assert!(accepted > iters / 20, "only {accepted} of {iters} inputs were accepted");
    assert!(rejected > iters / 20, "only {rejected} of {iters} inputs were rejected");
}
