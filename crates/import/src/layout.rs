//! The PhysicalAI-AV tree on disk: where each feature of a chunk lives, which members of its
//! zip belong to a clip, and the clip index.
//!
//! ```text
//! ROOT/
//!   features.csv                     feature → chunk_path, clip_files_in_zip (optional here)
//!   clip_index.parquet               clip_id → chunk (+ split, clip_is_valid)
//!   camera/<cam>/<cam>.chunk_0000.zip      {clip}.<cam>.mp4, {clip}.<cam>.timestamps.parquet, …
//!   labels/egomotion/egomotion.chunk_0000.zip   {clip}.egomotion.parquet
//! ```
//!
//! `features.csv` is the dataset's own description of this layout (what its devkit reads):
//! per feature a `chunk_path` template (`camera/…/….chunk_{chunk_id:04d}.zip`) and a JSON
//! object `clip_files_in_zip` of member templates (`{"video": "{clip_id}.….mp4", …}`).
//! When it is present its templates are used; when it is absent, the layout above.
//! Zip members are read into memory one at a time; nothing is unpacked to disk.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Read as _;
use std::path::{Path, PathBuf};

use fogline_types::clip::CameraId;

use crate::error::{ImportError, Result};
use crate::table::Table;

/// The dataset's description of its files.
pub const FEATURES_CSV: &str = "features.csv";
/// The clip index.
pub const CLIP_INDEX: &str = "clip_index.parquet";
/// The feature name of the egomotion labels.
pub const EGOMOTION: &str = "egomotion";
/// A zip member larger than this is refused (a 20 s 1080p video is tens of MB).
pub const MAX_MEMBER_BYTES: u64 = 2 << 30;

/// One feature's files: the chunk file and, for zipped features, the members of a clip.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Feature {
    /// The chunk file, relative to the root, with `{chunk_id…}`.
    pub chunk_path: String,
    /// Member alias (`video`, `frame_timestamps`, `egomotion`) → template with `{clip_id}`.
    pub members: BTreeMap<String, String>,
}

/// A row of the clip index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IndexRow {
    /// The clip id (a UUID in the dataset).
    pub clip_id: String,
    /// Its chunk.
    pub chunk: i64,
    /// Its split (`train`, `val`, `test`), when the index says.
    pub split: Option<String>,
    /// Whether the dataset marks it valid, when the index says.
    pub valid: Option<bool>,
}

/// A PhysicalAI-AV tree.
#[derive(Debug, Clone)]
pub struct Layout {
    root: PathBuf,
    features: BTreeMap<String, Feature>,
    from_csv: bool,
}

impl Layout {
    /// Opens the tree at `root`: reads `features.csv` when there is one.
    pub fn open(root: &Path) -> Result<Self> {
        if !root.is_dir() {
            return Err(ImportError::data(
                root.display().to_string(),
                "not a directory (expected the root of a PhysicalAI-AV download, holding \
                 clip_index.parquet)",
            ));
        }
        let csv = root.join(FEATURES_CSV);
        let (features, from_csv) = if csv.is_file() {
            (read_features(&csv)?, true)
        } else {
            (default_features(), false)
        };
        Ok(Self {
            root: root.to_path_buf(),
            features,
            from_csv,
        })
    }

    /// The root.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Whether the layout came from `features.csv` (else the documented default).
    pub fn from_features_csv(&self) -> bool {
        self.from_csv
    }

    fn feature(&self, name: &str) -> Result<&Feature> {
        self.features.get(name).ok_or_else(|| {
            ImportError::data(
                self.root.join(FEATURES_CSV).display().to_string(),
                format!("no feature `{name}`"),
            )
        })
    }

    /// The chunk file of `feature`.
    pub fn chunk_file(&self, feature: &str, chunk: i64) -> Result<PathBuf> {
        let f = self.feature(feature)?;
        let rel = format_template(&f.chunk_path, &[("chunk_id", Value::Int(chunk))])
            .map_err(|e| self.template_error(feature, "chunk_path", &e))?;
        let rel = Path::new(&rel);
        if rel.is_absolute() || rel.components().any(|c| c.as_os_str() == "..") {
            return Err(self.template_error(
                feature,
                "chunk_path",
                "a path outside the root (absolute or with `..`)",
            ));
        }
        Ok(self.root.join(rel))
    }

    /// The name of member `alias` of `clip_id` in the chunk zip of `feature`.
    pub fn member(&self, feature: &str, alias: &str, clip_id: &str) -> Result<String> {
        let f = self.feature(feature)?;
        let t = f.members.get(alias).ok_or_else(|| {
            self.template_error(
                feature,
                "clip_files_in_zip",
                &format!("no member `{alias}`"),
            )
        })?;
        format_template(t, &[("clip_id", Value::Str(clip_id))])
            .map_err(|e| self.template_error(feature, "clip_files_in_zip", &e))
    }

    fn template_error(&self, feature: &str, column: &str, detail: &str) -> ImportError {
        ImportError::data(
            self.root.join(FEATURES_CSV).display().to_string(),
            format!("feature `{feature}`, column `{column}`: {detail}"),
        )
    }

    /// Reads `clip_index.parquet`: the columns `clip_id` and `chunk`, and `split` and
    /// `clip_is_valid` when present.
    pub fn clip_index(&self) -> Result<Vec<IndexRow>> {
        let path = self.root.join(CLIP_INDEX);
        let bytes = std::fs::read(&path).map_err(|e| ImportError::io(&path, e))?;
        let t = Table::read(&path.display().to_string(), bytes)?;
        let ids = t.str_column("clip_id")?;
        let chunks = t.i64_column("chunk")?;
        let split = if t.has("split") {
            Some(t.str_column("split")?)
        } else {
            None
        };
        let valid = t.opt_bool_column("clip_is_valid")?;
        Ok(ids
            .into_iter()
            .zip(chunks)
            .enumerate()
            .map(|(i, (clip_id, chunk))| IndexRow {
                clip_id,
                chunk,
                split: split.as_ref().map(|s| s[i].clone()),
                valid: valid.as_ref().map(|v| v[i]),
            })
            .collect())
    }
}

/// The feature name of a camera (`camera_front_wide_120fov`).
pub fn camera_feature(camera: CameraId) -> &'static str {
    camera.name()
}

/// The layout described in `interfaces.md`, for trees without `features.csv`.
fn default_features() -> BTreeMap<String, Feature> {
    let mut m = BTreeMap::new();
    for cam in CameraId::ALL {
        let c = cam.name();
        m.insert(
            c.to_string(),
            Feature {
                chunk_path: format!("camera/{c}/{c}.chunk_{{chunk_id:04d}}.zip"),
                members: BTreeMap::from([
                    ("video".to_string(), format!("{{clip_id}}.{c}.mp4")),
                    (
                        "frame_timestamps".to_string(),
                        format!("{{clip_id}}.{c}.timestamps.parquet"),
                    ),
                ]),
            },
        );
    }
    m.insert(
        EGOMOTION.to_string(),
        Feature {
            chunk_path: "labels/egomotion/egomotion.chunk_{chunk_id:04d}.zip".to_string(),
            members: BTreeMap::from([(
                EGOMOTION.to_string(),
                "{clip_id}.egomotion.parquet".to_string(),
            )]),
        },
    );
    m
}

/// Reads `features.csv`: columns `feature`, `chunk_path` and `clip_files_in_zip` (a JSON
/// object of member templates, empty for features that are not zipped); others are ignored.
fn read_features(path: &Path) -> Result<BTreeMap<String, Feature>> {
    let loc = path.display().to_string();
    let mut r = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| ImportError::data(&loc, format!("not a readable CSV file: {e}")))?;
    let headers = r
        .headers()
        .map_err(|e| ImportError::data(&loc, format!("not a readable CSV file: {e}")))?
        .clone();
    let col = |name: &str| {
        headers.iter().position(|h| h == name).ok_or_else(|| {
            ImportError::data(
                &loc,
                format!(
                    "no column `{name}` (the header is: {})",
                    headers.iter().collect::<Vec<_>>().join(", ")
                ),
            )
        })
    };
    let (cf, cp, cm) = (
        col("feature")?,
        col("chunk_path")?,
        col("clip_files_in_zip")?,
    );
    let mut out = BTreeMap::new();
    for (i, rec) in r.records().enumerate() {
        let row = i as u64 + 1;
        let rec = rec.map_err(|e| ImportError::data(&loc, format!("row {row}: {e}")))?;
        let get = |k: usize| rec.get(k).unwrap_or_default();
        let name = get(cf).to_string();
        if name.is_empty() {
            return Err(ImportError::cell(&loc, row, "feature", "empty"));
        }
        let members: BTreeMap<String, String> = if get(cm).is_empty() {
            BTreeMap::new()
        } else {
            serde_json::from_str(get(cm)).map_err(|e| {
                ImportError::cell(
                    &loc,
                    row,
                    "clip_files_in_zip",
                    format!("expected a JSON object of member names: {e}"),
                )
            })?
        };
        out.insert(
            name,
            Feature {
                chunk_path: get(cp).to_string(),
                members,
            },
        );
    }
    Ok(out)
}

/// A value substituted into a template.
#[derive(Debug, Clone, Copy)]
pub enum Value<'a> {
    /// Text (`{clip_id}`).
    Str(&'a str),
    /// An integer (`{chunk_id:04d}`).
    Int(i64),
}

/// Python's `str.format` for the templates of `features.csv`: `{name}`, `{name:d}`,
/// `{name:0Nd}`, `{name:Nd}` and the escapes `{{` and `}}`.
pub fn format_template(t: &str, vars: &[(&str, Value<'_>)]) -> std::result::Result<String, String> {
    let mut out = String::with_capacity(t.len() + 16);
    let mut chars = t.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '{' if chars.peek() == Some(&'{') => {
                chars.next();
                out.push('{');
            }
            '}' if chars.peek() == Some(&'}') => {
                chars.next();
                out.push('}');
            }
            '}' => return Err(format!("template {t:?} has a single `}}`")),
            '{' => {
                let mut field = String::new();
                loop {
                    match chars.next() {
                        Some('}') => break,
                        Some(c) => field.push(c),
                        None => return Err(format!("template {t:?} has an unclosed `{{`")),
                    }
                }
                let (name, spec) = field.split_once(':').unwrap_or((&field, ""));
                let value = vars
                    .iter()
                    .find(|(n, _)| *n == name)
                    .map(|(_, v)| *v)
                    .ok_or_else(|| format!("template {t:?} names an unknown field `{name}`"))?;
                match (value, spec) {
                    (Value::Str(s), "" | "s") => out.push_str(s),
                    (Value::Int(v), "" | "d") => out.push_str(&v.to_string()),
                    (Value::Int(v), spec) => {
                        let digits = spec.strip_suffix('d').ok_or_else(|| {
                            format!("template {t:?}: unsupported format `{spec}`")
                        })?;
                        let (zero, width) = match digits.strip_prefix('0') {
                            Some(w) => (true, w),
                            None => (false, digits),
                        };
                        let width: usize =
                            width.parse().ok().filter(|w| *w <= 64).ok_or_else(|| {
                                format!("template {t:?}: unsupported format `{spec}`")
                            })?;
                        if zero {
                            out.push_str(&format!("{v:0width$}"));
                        } else {
                            out.push_str(&format!("{v:width$}"));
                        }
                    }
                    (Value::Str(_), spec) => {
                        return Err(format!(
                            "template {t:?}: unsupported format `{spec}` for text"
                        ));
                    }
                }
            }
            c => out.push(c),
        }
    }
    Ok(out)
}

/// A chunk zip, open for reading members one at a time.
#[derive(Debug)]
pub struct Archive {
    path: PathBuf,
    zip: zip::ZipArchive<File>,
}

impl Archive {
    /// Opens the zip at `path` (reads its central directory only).
    pub fn open(path: &Path) -> Result<Self> {
        let f = File::open(path).map_err(|e| ImportError::io(path, e))?;
        let zip = zip::ZipArchive::new(f).map_err(|e| {
            ImportError::data(
                path.display().to_string(),
                format!("not a readable zip: {e}"),
            )
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            zip,
        })
    }

    /// `archive.zip: member`, how errors name a member.
    pub fn location(&self, member: &str) -> String {
        format!("{}: {member}", self.path.display())
    }

    /// Reads member `name` into memory (checking its CRC).
    pub fn read(&mut self, name: &str) -> Result<Vec<u8>> {
        let loc = self.location(name);
        let mut f = match self.zip.by_name(name) {
            Ok(f) => f,
            Err(zip::result::ZipError::FileNotFound) => {
                return Err(ImportError::data(
                    loc,
                    "no such member in the zip (is the chunk complete?)",
                ));
            }
            Err(e) => {
                return Err(ImportError::data(
                    loc,
                    format!("cannot read the member: {e}"),
                ));
            }
        };
        let size = f.size();
        if size > MAX_MEMBER_BYTES {
            return Err(ImportError::data(
                loc,
                format!("{size} bytes, more than the {MAX_MEMBER_BYTES} a member may have"),
            ));
        }
        let mut out = Vec::with_capacity(size.min(64 << 20) as usize);
        f.by_ref()
            .take(MAX_MEMBER_BYTES + 1)
            .read_to_end(&mut out)
            .map_err(|e| ImportError::data(&loc, format!("cannot read the member: {e}")))?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn python_format_templates() {
        let vars = [
            ("chunk_id", Value::Int(7)),
            ("clip_id", Value::Str("ab-12")),
        ];
        let f = |t: &str| format_template(t, &vars);
        assert_eq!(
            f("camera/c/c.chunk_{chunk_id:04d}.zip").unwrap(),
            "camera/c/c.chunk_0007.zip"
        );
        assert_eq!(
            f("{clip_id}.egomotion.parquet").unwrap(),
            "ab-12.egomotion.parquet"
        );
        assert_eq!(f("{{x}}_{chunk_id}_{chunk_id:3d}").unwrap(), "{x}_7_  7");
        assert!(f("{nope}").unwrap_err().contains("unknown field `nope`"));
        assert!(f("{clip_id:04d}").unwrap_err().contains("unsupported"));
        assert!(f("{chunk_id:x}").unwrap_err().contains("unsupported"));
        assert!(f("{chunk_id").unwrap_err().contains("unclosed"));
        assert!(f("a}b").unwrap_err().contains("single"));
    }

    #[test]
    fn features_csv_or_the_default_layout() {
        let dir = tempfile::tempdir().unwrap();
        let l = Layout::open(dir.path()).unwrap();
        assert!(!l.from_features_csv());
        assert_eq!(
            l.chunk_file(EGOMOTION, 3).unwrap(),
            dir.path().join("labels/egomotion/egomotion.chunk_0003.zip")
        );
        assert_eq!(
            l.member("camera_front_tele_30fov", "video", "u-1").unwrap(),
            "u-1.camera_front_tele_30fov.mp4"
        );
        std::fs::write(
            dir.path().join(FEATURES_CSV),
            "feature,directory,chunk_path,clip_files_in_zip\n\
             egomotion,labels,\"ego/e_{chunk_id:03d}.zip\",\"{\"\"egomotion\"\": \"\"{clip_id}.ego.parquet\"\"}\"\n\
             clip_index,metadata,clip_index.parquet,\n\
             evil,labels,../outside_{chunk_id}.zip,\n",
        )
        .unwrap();
        let l = Layout::open(dir.path()).unwrap();
        assert!(l.from_features_csv());
        assert_eq!(
            l.chunk_file(EGOMOTION, 3).unwrap(),
            dir.path().join("ego/e_003.zip")
        );
        assert_eq!(
            l.member(EGOMOTION, EGOMOTION, "c").unwrap(),
            "c.ego.parquet"
        );
        let e = l
            .member("camera_front_wide_120fov", "video", "c")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("features.csv") && e.contains("no feature `camera_front_wide_120fov`"),
            "{e}"
        );
        let e = l.chunk_file("evil", 1).unwrap_err().to_string();
        assert!(e.contains("outside the root"), "{e}");
        std::fs::write(
            dir.path().join(FEATURES_CSV),
            "feature,chunk_path,clip_files_in_zip\negomotion,x.zip,\"[1, 2]\"\n",
        )
        .unwrap();
        let e = Layout::open(dir.path()).unwrap_err().to_string();
        assert!(e.contains("row 1, column `clip_files_in_zip`"), "{e}");
        std::fs::write(dir.path().join(FEATURES_CSV), "name,path\n").unwrap();
        let e = Layout::open(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("no column `feature`") && e.contains("name, path"),
            "{e}"
        );
    }

    #[test]
    fn members_read_in_place() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.zip");
        let mut w = zip::ZipWriter::new(File::create(&path).unwrap());
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        w.start_file("x.bin", opts).unwrap();
        std::io::Write::write_all(&mut w, &[7u8; 1000]).unwrap();
        w.finish().unwrap();
        let mut a = Archive::open(&path).unwrap();
        assert_eq!(a.read("x.bin").unwrap(), vec![7u8; 1000]);
        let e = a.read("y.bin").unwrap_err().to_string();
        assert!(
            e.ends_with("a.zip: y.bin: no such member in the zip (is the chunk complete?)"),
            "{e}"
        );
        std::fs::write(&path, b"PK\x03\x04 truncated").unwrap();
        let e = Archive::open(&path).unwrap_err().to_string();
        assert!(e.contains("a.zip: not a readable zip"), "{e}");
    }
}
