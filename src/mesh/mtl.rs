//! Wavefront material libraries (`.mtl`), as referenced by an OBJ's `mtllib` statements.
//!
//! Hand-written, like the OBJ reader, so that errors name the line. Only what the pipeline uses
//! is read: `newmtl name`, the diffuse colour `Kd r [g b]` and the diffuse texture
//! `map_Kd [options] file` (options such as `-s 1 1 1` are skipped; the file is the rest of
//! the line, spaces and all, without the quotes some exporters put around it). Other
//! statements (`Ka`, `Ks`, `Ns`, `d`, `illum`, other maps, ...) are ignored. Bytes that are
//! not UTF-8 (Latin-1 names) are replaced, as in the OBJ's words.
//!
//! Paths: `mtllib` names are resolved relative to the OBJ's directory, `map_Kd` names relative to
//! the `.mtl`'s directory. A missing library, a missing or unreadable texture, a library or
//! texture path that is not a regular file, a texture over [`Texture::load`]'s size limits and a
//! `usemtl` naming no known material are warnings ([`Mesh::warnings`]), and the affected faces
//! fall back to the material's `Kd` (or the default grey); so is a line of a `.mtl` that cannot
//! be read, which is named and ignored.

use std::collections::{HashMap, HashSet};
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

use super::obj::MaterialStatements;
use super::{Material, Mesh};
use crate::error::Error;
use crate::texture::{MAX_TEXELS, MAX_TEXTURE_SIDE, Texture};

/// The materials of one `.mtl` file, in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialLibrary {
    /// One entry per `newmtl`; `diffuse_texture` is resolved against the library's directory
    /// but not checked for existence (see [`apply`]).
    pub materials: Vec<Material>,
    /// The line of each material's `map_Kd` (0 where it has none), for warnings about the
    /// texture to name.
    pub texture_lines: Vec<usize>,
    /// Statements that were understood but not supported (`Kd spectral ...`, say).
    pub warnings: Vec<String>,
}

/// Reads and parses a `.mtl` file; texture paths are resolved relative to its directory.
/// Warnings name the file and line (`lib.mtl:9: ...`), as the OBJ reader's do.
pub fn read(path: &Path) -> Result<MaterialLibrary, Error> {
    let bytes = crate::input::read(path)?;
    let dir = path.parent().unwrap_or_else(|| Path::new(""));
    library(&bytes, dir, Some(path)).map_err(|(line, message)| Error::Parse {
        path: path.to_path_buf(),
        line,
        message,
    })
}

/// Lines of a library that cannot be read and are each named in a warning; the ones after
/// are counted in one more.
const MAX_IGNORED_WARNINGS: usize = 20;

/// Parses `.mtl` text, resolving `map_Kd` file names against `dir`. A line that cannot be
/// read (`Kd 0,5 0,5 0,5`, `Kd` before any `newmtl`, `map_Kd` without a file) is ignored
/// with a warning naming it (`line 9: ...`): a material library only colours the model, and
/// one bad line had stopped the whole model from loading. The `Err` is kept for reading
/// errors of the underlying lines, which a slice does not have.
pub fn parse(bytes: &[u8], dir: &Path) -> Result<MaterialLibrary, (usize, String)> {
    library(bytes, dir, None)
}

/// [`parse`], its warnings naming `file` and the line where there is a file, the line alone
/// where not.
fn library(
    bytes: &[u8],
    dir: &Path,
    file: Option<&Path>,
) -> Result<MaterialLibrary, (usize, String)> {
    let mut lib = MaterialLibrary::default();
    // Each warning's line and text, in line order.
    let mut notes = Vec::new();
    let mut ignored = 0usize;
    // The line of each name's first `newmtl`.
    let mut first = HashMap::new();
    let io = |e: std::io::Error| (0, e.to_string());
    super::read_lines(bytes, io, |raw, line| {
        let read = statement(&mut lib, (&mut notes, &mut first), raw, line, dir);
        if let Err((line, message)) = read {
            ignored += 1;
            if ignored <= MAX_IGNORED_WARNINGS {
                notes.push((line, format!("{message}; the line is ignored")));
            }
        }
        Ok(())
    })?;
    lib.warnings = (notes.into_iter())
        .map(|(line, note)| match file {
            Some(file) => format!("{}:{line}: {note}", file.display()),
            None => format!("line {line}: {note}"),
        })
        .collect();
    // Said first: after the lines it names, a reader that shows the first warnings only (the
    // CLI shows 20) had hidden it, and with it how many lines were lost ("1 more warning").
    if ignored > MAX_IGNORED_WARNINGS {
        let file = file.map_or(String::new(), |file| format!("{}: ", file.display()));
        let count = format!("{ignored} lines cannot be read and are ignored");
        let named = format!("the first {MAX_IGNORED_WARNINGS} are named below");
        lib.warnings.insert(0, format!("{file}{count}; {named}"));
    }
    Ok(lib)
}

/// One line of a `.mtl` file into `lib`, a warning of it into `notes` as its line and text;
/// `first` has the line of each material name's first `newmtl`.
fn statement(
    lib: &mut MaterialLibrary,
    (notes, first): (&mut Vec<(usize, String)>, &mut HashMap<String, usize>),
    raw: &[u8],
    line: usize,
    dir: &Path,
) -> Result<(), (usize, String)> {
    let text = super::statement_text(raw);
    let mut tokens = text.split_ascii_whitespace();
    let Some(keyword) = tokens.next() else {
        return Ok(());
    };
    let args: Vec<&str> = tokens.collect();
    // Keywords are matched case-insensitively (`map_kd` occurs in the wild).
    let lower = keyword.to_ascii_lowercase();
    if lower == "newmtl" {
        if args.is_empty() {
            return Err((line, "`newmtl` needs a material name".into()));
        }
        let name = args.join(" ");
        // Kept, so that later lines still belong to a material, but named in a warning: the
        // OBJ's faces take the first (see `apply`), and an exporter that wrote the name twice
        // has likely lost one of the two materials.
        match first.get(&name) {
            Some(&at) => notes.push((
                line,
                format!(
                    "material `{name}` is defined again (first on line {at}); faces use the \
                     first definition"
                ),
            )),
            None => {
                first.insert(name.clone(), line);
            }
        }
        lib.materials.push(Material { name, ..Material::default() });
        lib.texture_lines.push(0);
        return Ok(());
    }
    if lower != "kd" && lower != "map_kd" {
        return Ok(());
    }
    let Some(material) = lib.materials.last_mut() else {
        return Err((line, format!("`{keyword}` before any `newmtl`")));
    };
    if lower == "kd" {
        if matches!(args.first(), Some(&("spectral" | "xyz"))) {
            let note = format!(
                "`Kd {}` is not supported; material `{}` keeps its default colour",
                args[0], material.name
            );
            notes.push((line, note));
            return Ok(());
        }
        let mut rgb = [0.0f32; 3];
        let f = args
            .iter()
            .enumerate()
            .map(|(k, a)| match a.parse::<f32>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => {
                    // Quoted from the line's bytes, as the OBJ reader quotes (`\xe9`, where
                    // the text has U+FFFD).
                    let word = super::statement_words(raw).nth(k + 1);
                    let a = word.map_or(std::borrow::Cow::Borrowed(*a), super::shown);
                    Err((line, format!("`Kd` expected a finite number, found `{a}`")))
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        match f.len() {
            1 => rgb = [f[0]; 3],
            3 => rgb.copy_from_slice(&f),
            k => return Err((line, format!("`Kd` takes r [g b], found {k} numbers"))),
        }
        if rgb.iter().any(|c| !(0.0..=1.0).contains(c)) {
            rgb = rgb.map(|c| c.clamp(0.0, 1.0));
            let note = format!(
                "`Kd {}` is outside [0, 1]; material `{}` takes it clamped, {} {} {}",
                args.join(" "),
                material.name,
                rgb[0],
                rgb[1],
                rgb[2]
            );
            notes.push((line, note));
        }
        material.diffuse = rgb;
    } else {
        let rest = &text.trim_start()[keyword.len()..];
        let Some(file) = texture_file(rest) else {
            return Err((line, "`map_Kd` needs a file name".into()));
        };
        material.diffuse_texture = Some(dir.join(file));
        if let Some(at) = lib.texture_lines.last_mut() {
            *at = line;
        }
    }
    Ok(())
}

/// The file name of a texture statement's arguments `rest`: what follows the options
/// (`-s 1 1 1`, `-clamp on`, ...), to the end of the line, so that a name with spaces is
/// whole (the last word alone had named another file); double quotes around it are removed.
/// An option takes its arguments as the MTL format gives them, the optional ones (`-s u [v
/// [w]]`) only when they are numbers.
fn texture_file(mut rest: &str) -> Option<&str> {
    fn split(text: &str) -> (&str, &str) {
        let text = text.trim_start();
        text.split_at(text.find(|c: char| c.is_ascii_whitespace()).unwrap_or(text.len()))
    }
    loop {
        let (word, after) = split(rest);
        // (required, at most) arguments.
        let (required, most) = match word {
            "-blendu" | "-blendv" | "-boost" | "-texres" | "-clamp" | "-bm" | "-imfchan"
            | "-cc" | "-type" => (1, 1),
            "-mm" => (1, 2),
            "-o" | "-s" | "-t" => (1, 3),
            _ => break,
        };
        rest = after;
        for k in 0..most {
            let (arg, after) = split(rest);
            if arg.is_empty() || (k >= required && arg.parse::<f32>().is_err()) {
                break;
            }
            rest = after;
        }
    }
    let name = rest.trim();
    let name = name.strip_prefix('"').and_then(|n| n.strip_suffix('"')).unwrap_or(name);
    (!name.is_empty()).then_some(name)
}

/// Resolves an OBJ's materials from its material statements `obj`: loads its `mtllib` files
/// (relative to `obj_path`'s directory) and fills in the colour and texture of every named
/// material in `mesh.materials` (as made by [`super::obj::parse_mesh`] or
/// [`super::obj::to_mesh`]). Problems that do not stop rendering go to `mesh.warnings`: a
/// missing or unreadable library or one that is not a regular file, a material no library
/// defines (not reported when a library is missing: it was probably there), a texture that is
/// missing, not a regular file, too large or whose header cannot be decoded (its
/// `diffuse_texture` is then `None`, leaving the `Kd` colour). Materials keep the default grey
/// when undefined. A library's lines that cannot be read are warnings naming the `.mtl` file
/// and line (see [`parse`]). A library named again (the same file, once resolved) is read
/// only where first named, and its warnings given once.
pub fn apply(mesh: &mut Mesh, obj: &MaterialStatements, obj_path: &Path) -> Result<(), Error> {
    let dir = obj_path.parent().unwrap_or_else(|| Path::new(""));
    let obj_name = obj_path.display();
    // Each material name's first definition: the material, its library and its `map_Kd` line.
    let mut defined: HashMap<String, (Material, PathBuf, usize)> = HashMap::new();
    // The libraries tried so far. Reading one again would define nothing, its names all having
    // their first definition already, and had repeated its warnings: 5000 `mtllib` lines of
    // one 20,000-material library took minutes.
    let mut tried: HashSet<PathBuf> = HashSet::new();
    let mut missing_library = false;
    for (argument, line) in &obj.libraries {
        for file in library_files(dir, argument) {
            // `m.mtl`, `./m.mtl` and a symlink to it are one file; a missing one keeps its name.
            if !tried.insert(std::fs::canonicalize(&file).unwrap_or_else(|_| file.clone())) {
                continue;
            }
            let lib = match read(&file) {
                Ok(lib) => lib,
                Err(Error::Io { source, .. }) => {
                    let why = if source.kind() == std::io::ErrorKind::NotFound {
                        "was not found".to_string()
                    } else {
                        format!("cannot be read ({source})")
                    };
                    mesh.warnings.push(format!(
                        "{obj_name}:{line}: material library {} {why}; using default materials",
                        file.display()
                    ));
                    missing_library = true;
                    continue;
                }
                Err(Error::NotRegularFile { kind, .. }) => {
                    mesh.warnings.push(format!(
                        "{obj_name}:{line}: material library {} is {kind}, not a regular file; \
                         using default materials",
                        file.display()
                    ));
                    missing_library = true;
                    continue;
                }
                Err(e) => return Err(e),
            };
            mesh.warnings.extend(lib.warnings);
            mesh.material_libraries.push(file.clone());
            for (m, at) in lib.materials.into_iter().zip(lib.texture_lines) {
                defined.entry(m.name.clone()).or_insert_with(|| (m, file.clone(), at));
            }
        }
    }
    let lines: HashMap<&str, u32> =
        obj.names.iter().map(|(name, line)| (name.as_str(), *line)).collect();
    for material in mesh.materials.iter_mut().filter(|m| !m.name.is_empty()) {
        let Some((found, library, texture_line)) = defined.get(&material.name) else {
            if missing_library {
                // Probably defined in the missing library, which has its warning already.
                continue;
            }
            let line = lines.get(material.name.as_str()).copied().unwrap_or(0);
            let why = if obj.libraries.is_empty() {
                "the file has no `mtllib`"
            } else {
                "no material library defines it"
            };
            mesh.warnings.push(format!(
                "{obj_name}:{line}: material `{}`: {why}; using the default colour",
                material.name
            ));
            continue;
        };
        material.diffuse = found.diffuse;
        material.diffuse_texture = None;
        material.texture_statement = None;
        if let Some(texture) = &found.diffuse_texture {
            match check_texture(texture) {
                Ok(path) => {
                    material.diffuse_texture = Some(path);
                    material.texture_statement = Some((library.clone(), *texture_line));
                }
                Err(why) => mesh.warnings.push(format!(
                    "{}:{texture_line}: texture {} of material `{}` {why}; using its diffuse \
                     colour",
                    library.display(),
                    texture.display(),
                    material.name
                )),
            }
        }
    }
    Ok(())
}

/// The files an `mtllib` argument names: the whole argument if such a file exists (names may
/// contain spaces), else each whitespace-separated name.
fn library_files(dir: &Path, argument: &str) -> Vec<PathBuf> {
    let whole = dir.join(argument);
    if whole.is_file() || !argument.contains(' ') {
        return vec![whole];
    }
    argument.split(' ').map(|f| dir.join(f)).collect()
}

/// Checks that a texture is a regular file whose header decodes to a size within the limits
/// of [`Texture::load`]; returns the path to use (a name written with Windows separators is
/// retried with `/`).
fn check_texture(path: &Path) -> Result<PathBuf, String> {
    let mut path = path.to_path_buf();
    let mut found = Texture::dimensions(&path);
    if matches!(&found, Err(Error::Io { source, .. }) if source.kind() == ErrorKind::NotFound) {
        let text = path.to_string_lossy();
        if !text.contains('\\') {
            return Err("was not found".into());
        }
        path = PathBuf::from(text.replace('\\', "/"));
        found = Texture::dimensions(&path);
    }
    match found {
        Ok(_) => Ok(path),
        Err(Error::Io { source, .. }) if source.kind() == ErrorKind::NotFound => {
            Err("was not found".into())
        }
        Err(Error::Io { source, .. }) => Err(format!("cannot be read ({source})")),
        Err(Error::NotRegularFile { kind, .. }) => Err(format!("is {kind}, not a regular file")),
        Err(Error::TextureSize { width, height, .. }) => Err(format!(
            "is {width}x{height} texels, more than a texture may have (at most {MAX_TEXTURE_SIDE} \
             a side and {MAX_TEXELS} in all)"
        )),
        Err(Error::Decode { message, .. }) => Err(format!("cannot be decoded ({message})")),
        Err(e) => Err(e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_kd_and_map_kd_with_options() {
        let src = b"# lib by Jos\xe9\nnewmtl a\nKd 1 0.5 0.25\nmap_kd -s 1 1 1 -o 0 0 tex/a.png\n\
                    newmtl b c\nKd 0.3\nKs 1 1 1\nnewmtl d\nKd 2 -1 0.5\n";
        let lib = parse(src, Path::new("models")).unwrap();
        assert_eq!(lib.materials.len(), 3);
        assert_eq!(lib.materials[0].diffuse, [1.0, 0.5, 0.25]);
        assert_eq!(lib.materials[0].diffuse_texture, Some(PathBuf::from("models/tex/a.png")));
        assert_eq!(lib.materials[1].name, "b c");
        assert_eq!(lib.materials[1].diffuse, [0.3; 3]);
        assert_eq!(lib.materials[2].diffuse, [1.0, 0.0, 0.5]);
        let clamped = "line 9: `Kd 2 -1 0.5` is outside [0, 1]; material `d` takes it clamped";
        assert_eq!(lib.warnings.len(), 1);
        assert!(lib.warnings[0].starts_with(clamped), "{:?}", lib.warnings);
    }

    /// A texture's name is the rest of the line after the options, so names with spaces are
    /// whole (the last word alone had named another file), quoted or not; optional option
    /// arguments are taken only when they are numbers.
    #[test]
    fn texture_names_are_the_rest_of_the_line() {
        let cases = [
            ("map_Kd my dir/blue tex.png", "my dir/blue tex.png"),
            ("map_Kd \"blue tex.png\"", "blue tex.png"),
            ("map_Kd   -s 2 2 -clamp on  blue tex.png  ", "blue tex.png"),
            ("map_Kd -o 0.5 -mm 0 1 -bm 2 a.png", "a.png"),
            ("map_Kd -s 1 2 3 4.png", "4.png"),
            (
                "map_Kd -imfchan r -cc off -texres 512 -blendu on -blendv off -boost 1 t.png",
                "t.png",
            ),
            ("map_Kd -unknown t.png", "-unknown t.png"),
            ("map_Kd plain.png", "plain.png"),
        ];
        for (statement, want) in cases {
            let lib = parse(format!("newmtl a\n{statement}\n").as_bytes(), Path::new("d")).unwrap();
            let got = lib.materials[0].diffuse_texture.clone();
            assert_eq!(got, Some(Path::new("d").join(want)), "{statement}");
        }
        for statement in ["map_Kd -s 1 1 1", "map_Kd -clamp on", "map_Kd \"\""] {
            let lib = parse(format!("newmtl a\n{statement}\n").as_bytes(), Path::new("")).unwrap();
            let want = "line 2: `map_Kd` needs a file name; the line is ignored";
            assert_eq!(lib.warnings, [want], "{statement}");
            assert_eq!(lib.materials[0].diffuse_texture, None);
        }
    }

    /// A line that cannot be read is ignored with a warning naming it, and the rest of the
    /// library is read: the material before it keeps what it had, the one after is whole.
    #[test]
    fn lines_that_cannot_be_read_are_warned_of_and_ignored() {
        let cases: &[(&[u8], usize, &str)] = &[
            (b"Kd 1 1 1\n", 1, "before any `newmtl`"),
            (b"newmtl a\nKd 1 x 1\n", 2, "found `x`"),
            (b"newmtl a\n\nKd 1 1\n", 3, "found 2 numbers"),
            (b"newmtl\n", 1, "needs a material name"),
            (b"newmtl a\nmap_Kd\n", 2, "needs a file name"),
            (b"newmtl a\nKd nan 0 0\n", 2, "finite"),
            (b"newmtl a\nKd 0,5 0,5 0,5\n", 2, "found `0,5`"),
            (b"newmtl a\nKd 0.5 0.5 0.5 1.0\n", 2, "found 4 numbers"),
            (b"newmtl a\nKd 1 1 \xe9\n", 2, "found `\\xe9`"),
        ];
        for (src, line, needle) in cases {
            let mut text = src.to_vec();
            text.extend_from_slice(b"newmtl z\nKd 0.25 0.5 0.75\nmap_Kd z.png\n");
            let lib = parse(&text, Path::new("")).unwrap();
            assert_eq!(lib.warnings.len(), 1, "{:?}", lib.warnings);
            let w = &lib.warnings[0];
            assert!(w.starts_with(&format!("line {line}: ")), "{w}");
            assert!(w.contains(needle) && w.ends_with("; the line is ignored"), "{w}: {needle}");
            let z = lib.materials.last().unwrap();
            assert_eq!((z.name.as_str(), z.diffuse), ("z", [0.25, 0.5, 0.75]));
            assert_eq!(z.diffuse_texture.as_deref(), Some(Path::new("z.png")));
            if let Some(a) = lib.materials.iter().find(|m| m.name == "a") {
                assert_eq!((a.diffuse, &a.diffuse_texture), (Material::default().diffuse, &None));
            }
        }
        // Twenty lines are named, all counted, the count first.
        let lib = parse("Kd 1\n".repeat(25).as_bytes(), Path::new("")).unwrap();
        assert_eq!(lib.warnings.len(), 21);
        let count = "25 lines cannot be read and are ignored; the first 20 are named below";
        assert_eq!(lib.warnings[0], count);
        assert!(lib.warnings[1].starts_with("line 1: `Kd` before any"), "{:?}", lib.warnings);
        assert_eq!(
            parse("Kd 1\n".repeat(20).as_bytes(), Path::new("")).unwrap().warnings.len(),
            20
        );
        // A file's warnings name it with the line, as the OBJ reader's do.
        let path = std::env::temp_dir().join(format!("trirast-mtl-{}.mtl", std::process::id()));
        std::fs::write(&path, "Kd 1\n".repeat(21) + "newmtl a\nKd 2 0 0\n").unwrap();
        let lib = read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let file = path.display();
        assert_eq!(lib.warnings.len(), 22);
        let count = "21 lines cannot be read and are ignored; the first 20 are named below";
        assert_eq!(lib.warnings[0], format!("{file}: {count}"));
        assert!(lib.warnings[1].starts_with(&format!("{file}:1: `Kd` before any")));
        assert!(lib.warnings[21].starts_with(&format!("{file}:23: `Kd 2 0 0` is outside")));
    }

    /// A name defined twice in a library is named in a warning with both lines; both
    /// definitions are kept in file order (faces take the first, see `apply`), and names that
    /// differ only in case are different materials.
    #[test]
    fn materials_defined_twice_are_warned_of() {
        let src = b"newmtl a b\nKd 1 0 0\nnewmtl A b\nnewmtl a  b\nKd 0 1 0\nnewmtl a b\n";
        let lib = parse(src, Path::new("")).unwrap();
        let names: Vec<&str> = lib.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["a b", "A b", "a b", "a b"]);
        assert_eq!(lib.materials[2].diffuse, [0.0, 1.0, 0.0]);
        let again = |line: usize| {
            format!(
                "line {line}: material `a b` is defined again (first on line 1); faces use the \
                 first definition"
            )
        };
        assert_eq!(lib.warnings, [again(4), again(6)]);
    }
}
