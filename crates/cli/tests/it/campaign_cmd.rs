//! `fogline campaign`: init, run, status, export, shards and merge through the binary, and
//! crash safety under SIGKILL.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::{fogline, text};

fn write_config(path: &Path, clips: usize, conditions: &str) {
    write_config_at(path, clips, conditions, (192, 108));
}

fn write_config_at(path: &Path, clips: usize, conditions: &str, (width, height): (u32, u32)) {
    std::fs::write(
        path,
        format!(
            "[clips]\ncount = {clips}\nseed = 5\nwidth = {width}\nheight = {height}\n\
             [conditions]\nnames = [{conditions}]\n[run]\nconcurrency = 2\n"
        ),
    )
    .unwrap();
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn init_run_status_export_and_refusals() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = d.join("campaign.toml");
    let o = fogline(&["campaign", "init", cfg.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(std::fs::read_to_string(&cfg).unwrap().contains("[planner]"));
    let o = fogline(&["campaign", "init", cfg.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "init does not overwrite");

    write_config(&cfg, 4, "\"noise_30\", \"dark\"");
    let out = d.join("out");
    let o = fogline(&[
        "campaign",
        "run",
        cfg.to_str().unwrap(),
        "--export",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("ran 12 runs"), "{t}");
    assert!(t.contains("pairs (seed 0): 8"), "{t}");
    let store = d.join("campaign.sqlite");
    assert!(store.is_file(), "the default store sits next to the config");
    for f in ["runs.csv", "runs.parquet", "pairs.csv", "pairs.parquet"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // The pairs table is what `fogline envelope` reads.
    let env = d.join("env");
    let o = fogline(&[
        "envelope",
        out.join("pairs.parquet").to_str().unwrap(),
        "--out",
        env.to_str().unwrap(),
        "--bootstrap",
        "50",
    ]);
    assert!(
        o.status.code() == Some(0) || o.status.code() == Some(1),
        "{}",
        text(&o)
    );
    assert!(env.join("envelope.json").is_file());

    // Status.
    let o = fogline(&["campaign", "status", store.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["planned"], 12);
    assert_eq!(v["ok"], 12);
    assert_eq!(v["pending"], 0);

    // Running again without --resume is refused; with --resume there is nothing to do.
    let o = fogline(&["campaign", "run", cfg.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("--resume"), "{}", text(&o));
    let o = fogline(&["campaign", "run", cfg.to_str().unwrap(), "--resume"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("ran 0 runs"), "{}", text(&o));

    // A changed configuration under the same store is refused, naming the change.
    write_config(&cfg, 5, "\"noise_30\", \"dark\"");
    let o = fogline(&["campaign", "run", cfg.to_str().unwrap(), "--resume"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("clips.count 4 → 5"), "{}", text(&o));

    // A bad configuration names the field.
    std::fs::write(
        &cfg,
        "[clips]\ncount = 4\n[planner]\nkind = \"egodriver\"\n",
    )
    .unwrap();
    let o = fogline(&[
        "campaign",
        "run",
        cfg.to_str().unwrap(),
        "--store",
        d.join("x.sqlite").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("planner.endpoint"), "{}", text(&o));
    assert!(
        !d.join("x.sqlite").exists(),
        "no store is left behind for a bad config"
    );

    // Not a store.
    let o = fogline(&["campaign", "status", cfg.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("not a fogline campaign store"),
        "{}",
        text(&o)
    );
}

#[test]
fn shards_run_by_the_binary_merge_into_the_unsharded_result() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = d.join("c.toml");
    write_config(&cfg, 5, "\"noise_50\"");
    let c = cfg.to_str().unwrap();
    let o = fogline(&[
        "campaign",
        "run",
        c,
        "--export",
        d.join("whole").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let mut shards = Vec::new();
    for i in 0..2 {
        let o = fogline(&[
            "campaign",
            "run",
            c,
            "--shard",
            &format!("{i}/2"),
            "--resume",
        ]);
        assert!(o.status.success(), "{}", text(&o));
        shards.push(d.join(format!("c.shard-{i}-of-2.sqlite")));
        assert!(shards[i].is_file());
    }
    let merged = d.join("merged.sqlite");
    let mut args = vec!["campaign", "merge", "--out", merged.to_str().unwrap()];
    args.extend(shards.iter().map(|p| p.to_str().unwrap()));
    let o = fogline(&args);
    assert!(o.status.success(), "{}", text(&o));
    let o = fogline(&[
        "campaign",
        "export",
        merged.to_str().unwrap(),
        "--out",
        d.join("m").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(files(&d.join("whole")), files(&d.join("m")));
    let o = fogline(&["campaign", "run", c, "--shard", "2/2"]);
    assert_eq!(o.status.code(), Some(2));
}

/// A deterministic stream of delays (SplitMix64), so the kill points are random yet
/// reproducible.
fn delays(seed: u64) -> impl Iterator<Item = u64> {
    let mut s = seed;
    std::iter::repeat_with(move || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    })
}

#[test]
fn a_campaign_killed_with_sigkill_again_and_again_resumes_to_the_uninterrupted_tables() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = d.join("crash.toml");
    // Full-size frames, so that the campaign lasts a few seconds and the kills land
    // throughout it.
    write_config_at(&cfg, 24, "\"noise_30\", \"fog_07\", \"dark\"", (576, 320));
    let c = cfg.to_str().unwrap();
    // The reference: one uninterrupted run.
    let whole = d.join("whole.sqlite");
    let o = fogline(&[
        "campaign",
        "run",
        c,
        "--store",
        whole.to_str().unwrap(),
        "--concurrency",
        "1",
    ]);
    assert!(o.status.success(), "{}", text(&o));

    let store = d.join("killed.sqlite");
    let mut kills = 0;
    let mut completed = false;
    for (attempt, r) in delays(20_261_121).enumerate().take(400) {
        let mut child = Command::new(env!("CARGO_BIN_EXE_fogline"))
            .args([
                "-q",
                "campaign",
                "run",
                c,
                "--store",
                store.to_str().unwrap(),
                "--resume",
                "--concurrency",
                "1",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Kill points spread over process start, clip generation, planning and commits;
        // after 30 kills the run is left to finish.
        if kills < 30 {
            std::thread::sleep(Duration::from_millis(10 + r % 140));
            if child.try_wait().unwrap().is_none() {
                child.kill().unwrap(); // SIGKILL
                child.wait().unwrap();
                kills += 1;
                continue;
            }
        }
        let o = child.wait_with_output().unwrap();
        assert!(o.status.success(), "attempt {attempt}: {}", text(&o));
        completed = true;
        break;
    }
    assert!(completed, "the campaign never completed");
    assert!(
        kills >= 20,
        "only {kills} kills landed before the campaign completed"
    );

    let o = fogline(&["campaign", "status", store.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["ok"], 24 * 4, "nothing lost, nothing duplicated");
    assert_eq!(v["failed"], 0);
    for (s, out) in [(&whole, "e1"), (&store, "e2")] {
        let o = fogline(&[
            "campaign",
            "export",
            s.to_str().unwrap(),
            "--out",
            d.join(out).to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
    }
    assert_eq!(
        files(&d.join("e1")),
        files(&d.join("e2")),
        "identical tables after {kills} kills"
    );
}

#[test]
fn a_campaign_killed_in_its_first_100_ms_resumes_every_time() {
    // Kills while the store is being created (the first tens of milliseconds) once wedged
    // it for good. 30 fresh stores, each killed at a random moment in its first 100 ms, then
    // resumed: each finishes with the uninterrupted run's tables (with the 30 kills of the
    // test above, 60 kills in all).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = d.join("start.toml");
    write_config_at(&cfg, 4, "\"noise_30\", \"dark\"", (576, 320));
    let c = cfg.to_str().unwrap();
    let whole = d.join("whole.sqlite");
    let o = fogline(&["campaign", "run", c, "--store", whole.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let o = fogline(&[
        "campaign",
        "export",
        whole.to_str().unwrap(),
        "--out",
        d.join("e-whole").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let expected = files(&d.join("e-whole"));
    let mut landed = 0;
    for (i, r) in delays(20_261_127).take(30).enumerate() {
        let store = d.join(format!("s{i}.sqlite"));
        let args = [
            "-q",
            "campaign",
            "run",
            c,
            "--store",
            store.to_str().unwrap(),
            "--resume",
        ];
        let mut child = Command::new(env!("CARGO_BIN_EXE_fogline"))
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(r % 100));
        if child.try_wait().unwrap().is_none() {
            landed += 1;
        }
        child.kill().ok(); // SIGKILL
        child.wait().unwrap();
        let o = fogline(&args);
        assert!(
            o.status.success(),
            "store {i} (killed after {} ms): {}",
            r % 100,
            text(&o)
        );
        let out = d.join(format!("e{i}"));
        let o = fogline(&[
            "campaign",
            "export",
            store.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(
            files(&out) == expected,
            "store {i}: tables differ from the uninterrupted run"
        );
    }
    assert!(
        landed >= 25,
        "only {landed} of 30 kills landed before the run ended"
    );
}

/// Parquet in every codec: `campaign export --format parquet:CODEC` writes it (zstd by
/// default), and `fogline envelope` reads each to the same analysis as the CSV export.
#[test]
fn exports_in_every_parquet_codec_read_back_as_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = d.join("campaign.toml");
    write_config(&cfg, 6, "\"noise_30\", \"fog_05\"");
    let o = fogline(&["campaign", "run", cfg.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let store = d.join("campaign.sqlite");
    let analyse = |pairs: &Path, name: &str| -> serde_json::Value {
        let out = d.join(name);
        let o = fogline(&[
            "-q",
            "envelope",
            pairs.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--bootstrap",
            "50",
        ]);
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("envelope.json")).unwrap()).unwrap();
        v.as_object_mut().unwrap().remove("input");
        v
    };
    let export = |format: &str, name: &str| {
        let out = d.join(name);
        let o = fogline(&[
            "campaign",
            "export",
            store.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--format",
            format,
        ]);
        assert!(o.status.success(), "{}", text(&o));
        out
    };
    let csv = analyse(&export("csv", "csv").join("pairs.csv"), "env-csv");
    let mut bytes = Vec::new();
    for codec in ["", ":zstd", ":snappy", ":gzip", ":lz4", ":brotli", ":none"] {
        let out = export(&format!("parquet{codec}"), &format!("pq{codec}"));
        let pairs = out.join("pairs.parquet");
        bytes.push(std::fs::read(&pairs).unwrap());
        assert_eq!(analyse(&pairs, &format!("env{codec}")), csv, "{codec}");
    }
    // The default is zstd; every codec writes other bytes (pytest checks each file's codec
    // with pyarrow).
    assert_eq!(bytes[0], bytes[1]);
    for i in 1..bytes.len() {
        for j in i + 1..bytes.len() {
            assert_ne!(bytes[i], bytes[j], "codecs {i} and {j} wrote the same file");
        }
    }
    let o = fogline(&[
        "campaign",
        "export",
        store.to_str().unwrap(),
        "--out",
        d.join("bad").to_str().unwrap(),
        "--format",
        "parquet:lzo",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("\"lzo\" is not a Parquet codec"),
        "{}",
        text(&o)
    );
}

#[test]
fn bench_campaign_times_every_remote_path_under_clean_and_noisy_frames() {
    // Two calls per path, one run: the structure and the figures' presence, not their size.
    let o = fogline(&[
        "bench", "campaign", "--clips", "0", "--calls", "2", "--runs", "1", "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let t = String::from_utf8_lossy(&o.stdout).into_owned();
    let json: serde_json::Value = serde_json::from_str(&t[t.find("\n{").unwrap()..]).unwrap();
    let conditions = json["remote_overhead"].as_array().unwrap();
    assert_eq!(conditions.len(), 2);
    for (c, name) in conditions.iter().zip(["clean", "noise_30"]) {
        assert_eq!(c["condition"], name);
        assert_eq!(
            (c["cameras"].as_u64(), c["frames_per_camera"].as_u64()),
            (Some(4), Some(4))
        );
        let paths = c["paths"].as_array().unwrap();
        assert_eq!(paths.len(), 5, "{c}");
        for p in paths {
            assert!(p["ms"].as_f64().unwrap() > 0.0, "{p}");
        }
        let codec = c["codec_one_thread"].as_array().unwrap();
        // Noise leaves deflate nothing: the wire PNG is stored, about the pixels' size.
        let png = codec[0]["bytes"].as_f64().unwrap() / (16.0 * 576.0 * 320.0 * 3.0);
        if name == "clean" {
            assert!(png < 0.5, "{png}");
        } else {
            assert!(png > 1.0 && png < 1.01, "{png}");
        }
    }
    assert!(t.contains("egodriver gRPC, jpeg95"), "{t}");
    assert!(t.contains("fogline's encoder, quality 95"), "{t}");
}
