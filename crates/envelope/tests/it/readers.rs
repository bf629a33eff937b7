//! Readers: every kind of bad input gets a clear error naming file, row and column.

use fogline_envelope::input::Format;
use fogline_envelope::{EnvelopeError, ReadOptions, read_pairs, read_pairs_bytes};
use proptest::prelude::*;

use crate::{csv, valid_csv};

const HEADER: &str = "clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\n";

fn msg(e: EnvelopeError) -> String {
    e.to_string()
}

#[test]
fn a_valid_file_reads_in_all_three_formats_identically() {
    let text = valid_csv(20);
    let a = csv(&text).unwrap();
    // JSONL from the same rows.
    let mut rdr = ::csv::Reader::from_reader(text.as_bytes());
    let headers = rdr.headers().unwrap().clone();
    let mut jsonl = String::new();
    for rec in rdr.records() {
        let rec = rec.unwrap();
        let mut obj = serde_json::Map::new();
        for (h, v) in headers.iter().zip(rec.iter()) {
            let val = match h {
                "ade_clean" | "ade_attacked" | "l2" => serde_json::json!(v.parse::<f64>().unwrap()),
                _ => serde_json::json!(v),
            };
            obj.insert(
                if h == "attack" {
                    "condition".into()
                } else {
                    h.into()
                },
                val,
            );
        }
        jsonl.push_str(&serde_json::Value::Object(obj).to_string());
        jsonl.push('\n');
    }
    let b = read_pairs_bytes(
        "t.jsonl",
        Format::Jsonl,
        jsonl.as_bytes(),
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(a.len(), 160);
    assert_eq!(a.ade_attacked_m, b.ade_attacked_m);
    assert_eq!(a.changed, b.changed);
    assert_eq!(a.jaccard, b.jaccard);
    assert_eq!(a.clip_ids, b.clip_ids);
}

#[test]
fn parquet_round_trip() {
    use arrow_array::{ArrayRef, Float64Array, RecordBatch, StringArray};
    use std::sync::Arc;
    let clips = ["a", "a", "b", "b"];
    let cols: Vec<(&str, ArrayRef)> = vec![
        ("clip_id", Arc::new(StringArray::from(clips.to_vec()))),
        ("scenario", Arc::new(StringArray::from(vec!["PASSING"; 4]))),
        (
            "attack",
            Arc::new(StringArray::from(vec![
                "noise_10", "fog_03", "noise_10", "fog_03",
            ])),
        ),
        (
            "ade_clean",
            Arc::new(Float64Array::from(vec![1.0, 1.0, 2.0, 2.0])),
        ),
        (
            "ade_attacked",
            Arc::new(Float64Array::from(vec![1.1, 1.5, 2.0, 2.2])),
        ),
        ("l2", Arc::new(Float64Array::from(vec![0.5, 3.0, 0.1, 9.0]))),
        (
            "coc_clean",
            Arc::new(StringArray::from(vec!["Keep lane."; 4])),
        ),
        (
            "coc_attacked",
            Arc::new(StringArray::from(vec![
                "Keep lane.",
                "Stop now.",
                "Keep lane.",
                "Slow down.",
            ])),
        ),
    ];
    let batch = RecordBatch::try_from_iter(cols).unwrap();
    let mut buf = Vec::new();
    let mut w = parquet::arrow::ArrowWriter::try_new(&mut buf, batch.schema(), None).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
    let t = read_pairs_bytes("t.parquet", Format::Parquet, &buf, &ReadOptions::default()).unwrap();
    assert_eq!(t.len(), 4);
    assert_eq!(t.changed, vec![false, true, false, true]);
    assert_eq!(t.conditions[1].level, 0.3);
    // Missing column in Parquet names the column.
    let batch2 = batch.project(&[0, 1, 2, 3, 4, 6, 7]).unwrap();
    let mut buf2 = Vec::new();
    let mut w = parquet::arrow::ArrowWriter::try_new(&mut buf2, batch2.schema(), None).unwrap();
    w.write(&batch2).unwrap();
    w.close().unwrap();
    let e = msg(
        read_pairs_bytes("t.parquet", Format::Parquet, &buf2, &ReadOptions::default()).unwrap_err(),
    );
    assert!(e.contains("missing column `l2`"), "{e}");
}

#[test]
fn bom_and_header_case_are_tolerated() {
    let t = csv("\u{feff}Clip_ID,Scenario,Attack,ADE_clean,ade_attacked,L2,coc_clean,coc_attacked\nc,PASSING,noise_10,1,1,1,a,a\n").unwrap();
    assert_eq!(t.clip_ids, vec!["c"]);
}

#[test]
fn parquet_dictionary_columns_read_as_text() {
    use arrow_array::{
        ArrayRef, DictionaryArray, Float64Array, RecordBatch, StringArray, types::Int32Type,
    };
    use std::sync::Arc;
    let scen: DictionaryArray<Int32Type> = vec!["PASSING", "PASSING"].into_iter().collect();
    let cols: Vec<(&str, ArrayRef)> = vec![
        ("clip_id", Arc::new(StringArray::from(vec!["a", "a"]))),
        ("scenario", Arc::new(scen)),
        (
            "attack",
            Arc::new(StringArray::from(vec!["noise_10", "noise_30"])),
        ),
        ("ade_clean", Arc::new(Float64Array::from(vec![1.0, 1.0]))),
        ("ade_attacked", Arc::new(Float64Array::from(vec![1.1, 1.5]))),
        ("l2", Arc::new(Float64Array::from(vec![0.5, 3.0]))),
        ("coc_clean", Arc::new(StringArray::from(vec!["Go."; 2]))),
        (
            "coc_attacked",
            Arc::new(StringArray::from(vec!["Go.", "Stop."])),
        ),
    ];
    let batch = RecordBatch::try_from_iter(cols).unwrap();
    let mut buf = Vec::new();
    let mut w = parquet::arrow::ArrowWriter::try_new(&mut buf, batch.schema(), None).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
    let t = read_pairs_bytes("t.parquet", Format::Parquet, &buf, &ReadOptions::default()).unwrap();
    assert_eq!(t.scenarios, vec!["PASSING"]);
    assert_eq!(t.changed, vec![false, true]);
}

#[test]
fn missing_and_misspelt_columns() {
    let e = msg(csv("clip_id,scenario,attack,ade_clen,ade_attacked,l2,coc_clean,coc_attacked\nc,S,noise_10,1,1,1,a,b\n").unwrap_err());
    assert!(
        e.contains("test.csv: missing column `ade_clean` (did you mean `ade_clen`?)"),
        "{e}"
    );
    let e = msg(csv(
        "clip_id,scenario,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\nc,S,1,1,1,a,b\n",
    )
    .unwrap_err());
    assert!(e.contains("missing column `attack (or condition)`"), "{e}");
    // `condition` is accepted for `attack`.
    csv("clip_id,scenario,condition,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\nc,S,noise_10,1,1,1,a,b\n").unwrap();
}

#[test]
fn bad_numbers_name_row_and_column() {
    for (value, expected) in [
        ("abc", "a finite number"),
        ("NaN", "a finite number"),
        ("inf", "a finite number"),
        ("-0.5", "a distance in metres (0 to 100000)"),
        ("2.7e178", "a distance in metres (0 to 100000)"),
        ("", "a finite number"),
    ] {
        let text = format!(
            "{HEADER}c1,PASSING,noise_10,1.0,1.2,0.4,Go.,Go.\nc1,PASSING,noise_30,1.0,{value},0.4,Go.,Go.\n"
        );
        let e = msg(csv(&text).unwrap_err());
        assert!(e.contains("test.csv: row 3, column `ade_attacked`"), "{e}");
        assert!(e.contains(expected), "{value}: {e}");
    }
}

#[test]
fn duplicate_pairs_name_both_rows() {
    let text = format!(
        "{HEADER}c1,PASSING,noise_10,1,1,1,a,a\nc2,PASSING,noise_10,1,1,1,a,a\nc1,PASSING,noise_10,1,1,1,a,a\n"
    );
    let e = msg(csv(&text).unwrap_err());
    assert!(
        e.contains("row 4 repeats clip \"c1\" under condition \"noise_10\" (first at row 2)"),
        "{e}"
    );
}

#[test]
fn incomplete_clips_are_refused_unless_allowed() {
    let text = format!(
        "{HEADER}c1,PASSING,noise_10,1,1,1,a,a\nc1,PASSING,noise_30,1,1,1,a,a\nc2,PASSING,noise_10,1,1,1,a,a\n"
    );
    let e = msg(csv(&text).unwrap_err());
    assert!(
        e.contains("1 of 2 clips lack some conditions (e.g. c2 (row 4): missing noise_30)"),
        "{e}"
    );
    let opts = ReadOptions {
        allow_incomplete: true,
        ..ReadOptions::default()
    };
    let t = read_pairs_bytes("t.csv", Format::Csv, text.as_bytes(), &opts).unwrap();
    assert_eq!(t.n_incomplete_clips, 1);
}

#[test]
fn unparseable_condition_needs_family_and_level() {
    let text = format!("{HEADER}c1,PASSING,blur_3,1,1,1,a,a\n");
    let e = msg(csv(&text).unwrap_err());
    assert!(e.contains("row 2, column `attack`: got \"blur_3\""), "{e}");
    assert!(e.contains("`family` and `level` columns"), "{e}");
    let ok = "clip_id,scenario,attack,family,level,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\nc1,PASSING,blur_3,motion_blur,3,1,1,1,a,a\n";
    let t = csv(ok).unwrap();
    assert_eq!(t.conditions[0].family.name(), "motion_blur");
    assert_eq!(t.conditions[0].level, 3.0);
    // inconsistent family/level for the same name
    let bad = "clip_id,scenario,attack,family,level,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\nc1,PASSING,blur_3,motion_blur,3,1,1,1,a,a\nc2,PASSING,blur_3,motion_blur,4,1,1,1,a,a\n";
    let e = msg(csv(bad).unwrap_err());
    assert!(e.contains("row 3, column `family/level`"), "{e}");
}

#[test]
fn a_clip_with_two_scenarios_is_refused() {
    let text = format!("{HEADER}c1,PASSING,noise_10,1,1,1,a,a\nc1,TURN_RIGHT,noise_30,1,1,1,a,a\n");
    let e = msg(csv(&text).unwrap_err());
    assert!(
        e.contains(
            "row 3: clip \"c1\" has scenario \"TURN_RIGHT\" but earlier rows say \"PASSING\""
        ),
        "{e}"
    );
}

#[test]
fn files_that_are_not_what_their_extension_says() {
    let dir = tempfile::tempdir().unwrap();
    let parquet_named_csv = dir.path().join("pairs.csv");
    std::fs::write(&parquet_named_csv, b"PAR1\x15\x04\x15\x00garbage").unwrap();
    let e = msg(read_pairs(&parquet_named_csv, &ReadOptions::default()).unwrap_err());
    assert!(
        e.contains("pairs.csv: not a valid CSV file: it looks like Parquet"),
        "{e}"
    );

    let csv_named_parquet = dir.path().join("pairs.parquet");
    std::fs::write(&csv_named_parquet, HEADER).unwrap();
    let e = msg(read_pairs(&csv_named_parquet, &ReadOptions::default()).unwrap_err());
    assert!(e.contains("pairs.parquet: not a valid Parquet file"), "{e}");

    let csv_named_jsonl = dir.path().join("pairs.jsonl");
    std::fs::write(&csv_named_jsonl, HEADER).unwrap();
    let e = msg(read_pairs(&csv_named_jsonl, &ReadOptions::default()).unwrap_err());
    assert!(
        e.contains("pairs.jsonl: not a valid JSON lines file: line 1"),
        "{e}"
    );

    let json_named_csv = dir.path().join("j.csv");
    std::fs::write(&json_named_csv, "{\"clip_id\": 1}\n").unwrap();
    let e = msg(read_pairs(&json_named_csv, &ReadOptions::default()).unwrap_err());
    assert!(e.contains("it looks like JSON"), "{e}");

    let txt = dir.path().join("pairs.txt");
    std::fs::write(&txt, HEADER).unwrap();
    let e = msg(read_pairs(&txt, &ReadOptions::default()).unwrap_err());
    assert!(e.contains("unsupported extension"), "{e}");

    let missing = dir.path().join("nope.csv");
    let e = read_pairs(&missing, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("cannot read"), "{e}");
    assert!(std::error::Error::source(&e).is_some());
}

#[test]
fn empty_files_and_ragged_rows() {
    let e = msg(csv(HEADER).unwrap_err());
    assert!(e.contains("no data rows"), "{e}");
    let e = msg(csv("").unwrap_err());
    assert!(e.contains("not a valid CSV file"), "{e}");
    let e = msg(csv(&format!("{HEADER}c1,PASSING,noise_10,1\n")).unwrap_err());
    assert!(e.contains("not a valid CSV file: line 2"), "{e}");
}

#[test]
fn jsonl_rows_missing_a_key_or_not_objects() {
    let line = r#"{"clip_id":"c","scenario":"PASSING","attack":"noise_10","ade_clean":1,"ade_attacked":1,"l2":1,"coc_clean":"a","coc_attacked":"a"}"#;
    let missing = r#"{"clip_id":"d","scenario":"PASSING","attack":"noise_10","ade_clean":1,"l2":1,"coc_clean":"a","coc_attacked":"a"}"#;
    let e = msg(read_pairs_bytes(
        "t.jsonl",
        Format::Jsonl,
        format!("{line}\n{missing}\n").as_bytes(),
        &ReadOptions::default(),
    )
    .unwrap_err());
    assert!(e.contains("t.jsonl: row 2, column `ade_attacked`"), "{e}");
    let e = msg(read_pairs_bytes(
        "t.jsonl",
        Format::Jsonl,
        format!("{line}\n[1,2]\n").as_bytes(),
        &ReadOptions::default(),
    )
    .unwrap_err());
    assert!(
        e.contains("line 2: expected one JSON object per line"),
        "{e}"
    );
    let e = msg(read_pairs_bytes(
        "t.jsonl",
        Format::Jsonl,
        format!("{line}\n{{\"x\": \n").as_bytes(),
        &ReadOptions::default(),
    )
    .unwrap_err());
    assert!(e.contains("line 2:"), "{e}");
}

#[test]
fn override_columns_are_validated() {
    let h = "clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked,coc_changed,jaccard\n";
    let t = csv(&format!("{h}c1,PASSING,noise_10,1,1,1,a,a,true,0.25\n")).unwrap();
    assert!(t.changed[0]);
    assert_eq!(t.jaccard[0], 0.25);
    let e = msg(csv(&format!("{h}c1,PASSING,noise_10,1,1,1,a,a,maybe,0.25\n")).unwrap_err());
    assert!(e.contains("column `coc_changed`"), "{e}");
    let e = msg(csv(&format!("{h}c1,PASSING,noise_10,1,1,1,a,a,1,1.5\n")).unwrap_err());
    assert!(
        e.contains("column `jaccard`") && e.contains("[0, 1]"),
        "{e}"
    );
}

fn check_no_panic(format: Format, bytes: &[u8]) {
    match read_pairs_bytes("fuzz", format, bytes, &ReadOptions::default()) {
        Ok(t) => {
            assert!(!t.is_empty());
            assert!(
                t.ade_clean_m
                    .iter()
                    .chain(&t.l2_m)
                    .all(|v| v.is_finite() && *v >= 0.0)
            );
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz"), "{e}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    /// Arbitrary bytes never panic any reader.
    #[test]
    fn fuzz_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        check_no_panic(Format::Csv, &bytes);
        check_no_panic(Format::Jsonl, &bytes);
        check_no_panic(Format::Parquet, &bytes);
    }

    /// Mutations of a valid file (byte flips, truncation, insertion) never panic, and a
    /// successful read holds only finite non-negative distances.
    #[test]
    fn fuzz_mutated_valid_files(pos in 0usize..4000, byte in any::<u8>(), cut in 0usize..4000, insert in proptest::collection::vec(any::<u8>(), 0..8)) {
        let base = valid_csv(6).into_bytes();
        let mut b = base.clone();
        let p = pos % b.len();
        b[p] = byte;
        check_no_panic(Format::Csv, &b);
        let mut c = base.clone();
        c.truncate(cut % base.len());
        check_no_panic(Format::Csv, &c);
        let mut d = base;
        let p = pos % d.len();
        d.splice(p..p, insert);
        check_no_panic(Format::Csv, &d);
    }

    /// Mutated JSON lines never panic.
    #[test]
    fn fuzz_mutated_jsonl(pos in 0usize..2000, byte in any::<u8>()) {
        let mut s = String::new();
        for i in 0..4 {
            s.push_str(&format!("{{\"clip_id\":\"c{i}\",\"scenario\":\"PASSING\",\"attack\":\"noise_10\",\"ade_clean\":1.5,\"ade_attacked\":2,\"l2\":3,\"coc_clean\":\"Go.\",\"coc_attacked\":\"Stop.\"}}\n"));
        }
        let mut b = s.into_bytes();
        let p = pos % b.len();
        b[p] = byte;
        check_no_panic(Format::Jsonl, &b);
    }
}

/// Arrow record batches (as a DataFrame hands them over) give the same table and the same
/// envelope as the CSV file they were parsed from, however they are chunked; a bad cell is
/// reported at its row across batches.
#[test]
fn arrow_batches_read_like_the_csv_file() {
    use std::sync::Arc;

    use arrow_array::{ArrayRef, Float64Array, RecordBatch, StringArray};
    use arrow_schema::{DataType, Field, Schema};

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small.csv");
    let from_csv =
        fogline_envelope::read_pairs(&path, &fogline_envelope::ReadOptions::default()).unwrap();
    let mut rdr = csv::Reader::from_path(&path).unwrap();
    let header: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    let rows: Vec<csv::StringRecord> = rdr.records().map(|r| r.unwrap()).collect();
    let numeric = |name: &str| name.starts_with("ade") || name == "l2";
    let schema = Arc::new(Schema::new(
        header
            .iter()
            .map(|h| {
                let t = if numeric(h) {
                    DataType::Float64
                } else {
                    DataType::Utf8
                };
                Field::new(h, t, true)
            })
            .collect::<Vec<_>>(),
    ));
    let batch_of = |rows: &[csv::StringRecord]| {
        let cols: Vec<ArrayRef> = header
            .iter()
            .enumerate()
            .map(|(k, h)| -> ArrayRef {
                if numeric(h) {
                    Arc::new(Float64Array::from_iter(
                        rows.iter().map(|r| r[k].parse::<f64>().ok()),
                    ))
                } else {
                    Arc::new(StringArray::from_iter(rows.iter().map(|r| Some(&r[k]))))
                }
            })
            .collect();
        RecordBatch::try_new(schema.clone(), cols).unwrap()
    };
    let read = |chunk: usize, rows: &[csv::StringRecord]| {
        let batches: Vec<Result<RecordBatch, std::convert::Infallible>> =
            rows.chunks(chunk).map(|c| Ok(batch_of(c))).collect();
        fogline_envelope::read_pairs_arrow(
            "frame",
            &schema,
            batches,
            &fogline_envelope::ReadOptions::default(),
        )
    };
    let one = read(rows.len(), &rows).unwrap();
    let many = read(97, &rows).unwrap();
    assert_eq!(one.input.sha256, many.input.sha256);
    assert_eq!(one.len(), from_csv.len());
    let p = crate::quick_params();
    let json = |t: &fogline_envelope::PairTable| {
        let mut v = serde_json::to_value(fogline_envelope::analyze(t, &p).unwrap()).unwrap();
        v.as_object_mut().unwrap().remove("input");
        v
    };
    let reference = json(&from_csv);
    assert_eq!(json(&one), reference);
    assert_eq!(json(&many), reference);

    // A negative ADE on data row 200 (in the third batch of 97) is reported as row 200.
    let mut bad = rows.clone();
    let k = header.iter().position(|h| h == "ade_attacked").unwrap();
    let mut fields: Vec<String> = bad[199].iter().map(String::from).collect();
    fields[k] = "-1".into();
    bad[199] = csv::StringRecord::from(fields);
    let err = read(97, &bad).unwrap_err().to_string();
    assert!(
        err.contains("frame") && err.contains("row 200") && err.contains("ade_attacked"),
        "{err}"
    );
}

/// The rows of `valid_csv(n)` as one Arrow batch (text columns as text, distances as f64).
fn batch_of(text: &str) -> arrow_array::RecordBatch {
    use arrow_array::{ArrayRef, Float64Array, StringArray};
    use std::sync::Arc;
    let mut rdr = ::csv::Reader::from_reader(text.as_bytes());
    let headers: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    let rows: Vec<::csv::StringRecord> = rdr.records().map(|r| r.unwrap()).collect();
    let cols: Vec<(String, ArrayRef)> = headers
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let a: ArrayRef = if matches!(h.as_str(), "ade_clean" | "ade_attacked" | "l2") {
                Arc::new(Float64Array::from_iter_values(
                    rows.iter().map(|r| r[i].parse::<f64>().unwrap()),
                ))
            } else {
                Arc::new(StringArray::from_iter_values(
                    rows.iter().map(|r| r[i].to_string()),
                ))
            };
            (h.clone(), a)
        })
        .collect();
    arrow_array::RecordBatch::try_from_iter(cols).unwrap()
}

#[test]
fn a_parquet_file_scrambled_mid_file_is_rejected_naming_it() {
    // Files as fogline's export writes them (Snappy pages) and uncompressed ones; 200 bytes
    // overwritten at a random place in the middle of each, 40 times.
    let text = valid_csv(150);
    let good = csv(&text).unwrap();
    let batch = batch_of(&text);
    for compression in [
        parquet::basic::Compression::SNAPPY,
        parquet::basic::Compression::UNCOMPRESSED,
    ] {
        let props = parquet::file::properties::WriterProperties::builder()
            .set_compression(compression)
            .build();
        let mut buf = Vec::new();
        let mut w =
            parquet::arrow::ArrowWriter::try_new(&mut buf, batch.schema(), Some(props)).unwrap();
        w.write(&batch).unwrap();
        w.close().unwrap();
        let clean =
            read_pairs_bytes("t.parquet", Format::Parquet, &buf, &ReadOptions::default()).unwrap();
        assert_eq!(clean.ade_attacked_m, good.ade_attacked_m);
        let mut state = 0x5EED_u64 ^ buf.len() as u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state >> 33
        };
        let (mut rejected, mut silent) = (0, Vec::new());
        for trial in 0..40 {
            let mut bad = buf.clone();
            let span = bad.len() * 6 / 10;
            let at = bad.len() / 5 + (next() as usize % span).min(bad.len() - 200);
            for b in &mut bad[at..at + 200] {
                *b = next() as u8;
            }
            match read_pairs_bytes("t.parquet", Format::Parquet, &bad, &ReadOptions::default()) {
                Err(e) => {
                    assert!(msg(e).contains("t.parquet"), "the error names the file");
                    rejected += 1;
                }
                Ok(t) => silent.push((trial, at, t.ade_attacked_m == good.ade_attacked_m)),
            }
        }
        assert!(
            silent.is_empty(),
            "{compression:?}: {rejected} of 40 scrambled files rejected; read without error: \
             {silent:?}"
        );
    }
}

#[test]
fn the_semantic_similarity_column_is_optional_nullable_and_validated() {
    let h = "clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked,coc_cosine\n";
    let t = csv(&format!(
        "{h}c1,PASSING,noise_10,1,1,1,a,b,0.75\nc2,PASSING,noise_10,1,1,1,a,b,\n"
    ))
    .unwrap();
    assert_eq!(t.cosine, vec![Some(0.75), None]);
    let t = csv("clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\nc,PASSING,noise_10,1,1,1,a,b\n").unwrap();
    assert_eq!(t.cosine, vec![None]);
    let e = msg(csv(&format!("{h}c1,PASSING,noise_10,1,1,1,a,b,1.5\n")).unwrap_err());
    assert!(
        e.contains("column `coc_cosine`") && e.contains("[-1, 1]"),
        "{e}"
    );
}
