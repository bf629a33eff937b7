//! Exports for fine-tuning and for DriveLM tooling:
//!
//! - `sharegpt/<split>_<task>.json`: LLaMA-Factory's ShareGPT format with images
//!   (`messages`, `images`, `system`; one `<image>` token per image, in order), one file per
//!   task (`object`, `motion`, `strategy`: the paper's appendix A.4 task prompts) and a joint
//!   one (`joint`: the controller's own hazard inference prompt, answered with its JSON
//!   schema), registered in `dataset_info.json`;
//! - `drivelm_qa.json`: DriveLM-style QA per clip (`key_object_infos`, `QA` with
//!   `perception`, `prediction`, `planning`, `behavior`, `image_paths`);
//! - `balance.md`: the class and label balance per split (figure 5b).

use std::collections::BTreeMap;

use fogline_rco::Strategy;
use fogline_rco::backend::prompt::SYSTEM_VISION;
use fogline_rco::deficit_eval::{HiddenClass, MotionLabel};
use fogline_types::clip::CameraId;
use serde_json::{Value, json};

use crate::DatasetError;
use crate::observe::{assessment, hazard_query, observations};
use crate::sample::{Manifest, SampleRecord, Split, SplitCounts};
use crate::scene::motion_phrase;

/// The tasks exported, one file each per split.
pub const TASKS: [&str; 4] = ["object", "motion", "strategy", "joint"];

/// The paper's task query prefix, adapted to our views and frame rate.
pub const PREFIX: &str = "This is a 5 s video, one frame per second, recorded by the cross-left, front-wide and cross-right cameras mounted on a moving ego vehicle. Certain regions of the frames are occluded with black masks and outlined with red bounding boxes to indicate areas with perception deficits.";

fn image_lines(sample: &SampleRecord) -> (String, Vec<String>) {
    let n = sample.frames.len();
    let mut text = String::new();
    let mut images = Vec::new();
    for (k, f) in sample.frames.iter().enumerate() {
        for v in &f.views {
            text.push_str(&format!(
                "\nImage: {} camera, {} s ago. <image>",
                v.camera.short(),
                n - 1 - k
            ));
            images.push(v.image.clone());
        }
    }
    (text, images)
}

fn strategy_word(s: Strategy) -> &'static str {
    match s {
        Strategy::Move => "Move",
        Strategy::StopObserveMove => "Stop",
    }
}

/// The ShareGPT record of one sample for `task`.
pub fn sharegpt_record(
    manifest: &Manifest,
    sample: &SampleRecord,
    task: &str,
) -> Result<Value, DatasetError> {
    let (images_text, images) = image_lines(sample);
    let object = sample.class.phrase();
    let motion = motion_phrase(sample.motion);
    let (user, answer) = match task {
        "object" => (
            format!(
                "{PREFIX}{images_text}\nThe black mask areas with red bounding boxes in the image are invisible. You need to infer the possible object in the invisible region. Return only one object, for example \"traffic light\"."
            ),
            object.to_string(),
        ),
        "motion" => (
            format!(
                "{PREFIX}{images_text}\nThe black mask areas with red bounding boxes in the image are invisible. You need to infer the motion behavior of the invisible region. For example, \"it is crossing paths with the ego vehicle\" or \"it is approaching from the opposite lane\"."
            ),
            format!("{motion}. {}", sample.rationale.motion),
        ),
        "strategy" => (
            format!(
                "{PREFIX}{images_text}\nThe black mask areas with red bounding boxes in the image may be a {object}, which is {motion}. You need to infer whether the ego vehicle should stop or move. Return your answer with either \"move\" or \"stop\" and a brief rationale explaining your answer."
            ),
            format!(
                "{}. {}",
                strategy_word(sample.strategy),
                sample.rationale.strategy
            ),
        ),
        "joint" => {
            let history = observations(manifest, sample, None)?;
            let a = assessment(&history);
            let q = hazard_query(&history, &a);
            let camera = sample.target_camera().unwrap_or(CameraId::FrontWide);
            let answer = json!({
                "hazards": [{
                    "camera": camera.short(),
                    "object": object,
                    "motion": motion,
                }],
                "strategy": sample.strategy.name(),
                "rationale": sample.rationale.strategy,
            });
            (format!("{}{images_text}", q.user), answer.to_string())
        }
        other => {
            return Err(DatasetError::Params(format!(
                "unknown task {other:?} (expected one of {})",
                TASKS.join(", ")
            )));
        }
    };
    Ok(json!({
        "system": SYSTEM_VISION,
        "messages": [
            {"role": "user", "content": user},
            {"role": "assistant", "content": answer},
        ],
        "images": images,
    }))
}

/// The `dataset_info.json` entry name of a split and task.
pub fn entry_name(split: Split, task: &str) -> String {
    format!("fogline_deficit_{}_{task}", split.name())
}

fn drivelm_camera(c: CameraId) -> &'static str {
    match c {
        CameraId::CrossLeft => "CAM_FRONT_LEFT",
        CameraId::FrontWide => "CAM_FRONT",
        CameraId::CrossRight => "CAM_FRONT_RIGHT",
        CameraId::FrontTele => "CAM_FRONT_TELE",
    }
}

/// The DriveLM-style QA of one sample.
pub fn drivelm_record(sample: &SampleRecord) -> Value {
    let mut image_paths = serde_json::Map::new();
    let mut key_objects = serde_json::Map::new();
    if let Some(last) = sample.frames.last() {
        for v in &last.views {
            let paths: Vec<&str> = sample
                .frames
                .iter()
                .filter_map(|f| f.views.iter().find(|w| w.camera == v.camera))
                .map(|w| w.image.as_str())
                .collect();
            image_paths.insert(drivelm_camera(v.camera).into(), json!(paths));
            for d in &v.deficits {
                let cx = (d[0] + d[2]) / 2;
                let cy = (d[1] + d[3]) / 2;
                key_objects.insert(
                    format!("<c1,{},{cx},{cy}>", drivelm_camera(v.camera)),
                    json!({
                        "Category": sample.class.phrase(),
                        "Status": sample.motion.name(),
                        "Visual_description": "hidden behind a perception deficit (black mask, red outline)",
                        "2d_bbox": [d[0], d[1], d[2], d[3]],
                    }),
                );
            }
        }
    }
    let qa = |q: &str, a: &str| json!({"Q": q, "A": a, "C": null, "con_up": null, "con_down": null, "cluster": null, "layer": null});
    let brake = match sample.strategy {
        Strategy::StopObserveMove => sample.rationale.strategy.clone(),
        Strategy::Move => "There is no reason for the ego vehicle to brake.".into(),
    };
    json!({
        "split": sample.split.name(),
        "key_frame": sample.frames.len().saturating_sub(1),
        "image_paths": image_paths,
        "key_object_infos": key_objects,
        "QA": {
            "perception": [qa("What object may be hidden in the black region with the red outline?", &format!("{} {}", sample.class.phrase(), sample.rationale.object))],
            "prediction": [qa("What is the hidden object doing?", &format!("{}. {}", motion_phrase(sample.motion), sample.rationale.motion))],
            "planning": [
                qa("Does the ego vehicle need to brake? Why?", &brake),
                qa("Should the ego vehicle move or stop, observe and then move?", &format!("{}. {}", sample.strategy.name(), sample.rationale.strategy)),
            ],
            "behavior": [],
        },
    })
}

/// Every export file, `(relative path, bytes)`.
pub fn exports(
    manifest: &Manifest,
    records: &[SampleRecord],
) -> Result<Vec<(String, Vec<u8>)>, DatasetError> {
    let mut out = Vec::new();
    let mut info = serde_json::Map::new();
    for split in Split::ALL {
        let of_split: Vec<&SampleRecord> = records.iter().filter(|r| r.split == split).collect();
        for task in TASKS {
            let list = of_split
                .iter()
                .map(|r| sharegpt_record(manifest, r, task))
                .collect::<Result<Vec<_>, _>>()?;
            let file = format!("sharegpt/{}_{task}.json", split.name());
            out.push((file.clone(), crate::pretty_json(&list)?));
            info.insert(
                entry_name(split, task),
                json!({
                    "file_name": file,
                    "formatting": "sharegpt",
                    "columns": {"messages": "messages", "images": "images", "system": "system"},
                    "tags": {"role_tag": "role", "content_tag": "content", "user_tag": "user", "assistant_tag": "assistant"},
                }),
            );
        }
    }
    out.push(("dataset_info.json".into(), crate::pretty_json(&info)?));
    let qa: serde_json::Map<String, Value> = records
        .iter()
        .map(|r| (r.id.clone(), drivelm_record(r)))
        .collect();
    out.push(("drivelm_qa.json".into(), crate::pretty_json(&qa)?));
    out.push((
        "balance.md".into(),
        balance_markdown(&manifest.counts).into_bytes(),
    ));
    Ok(out)
}

/// The class and label balance (figure 5b) as Markdown: per split, samples per class with
/// `move` / `stop-observe-move` and the motion labels.
pub fn balance_markdown(counts: &BTreeMap<String, SplitCounts>) -> String {
    let mut s = String::from("# DriveLM-Deficit balance (figure 5b)\n");
    for key in ["all", "train", "val", "test"] {
        let Some(c) = counts.get(key) else { continue };
        s.push_str(&format!(
            "\n## {key}: {} samples, {} towns\n\n| class | samples | move | stop-observe-move |",
            c.samples, c.towns
        ));
        for m in MotionLabel::ALL {
            s.push_str(&format!(" {} |", m.name()));
        }
        s.push_str("\n|---|---:|---:|---:|");
        for _ in MotionLabel::ALL {
            s.push_str("---:|");
        }
        s.push('\n');
        for class in HiddenClass::ALL {
            let Some(cc) = c.by_class.get(class.name()) else {
                continue;
            };
            s.push_str(&format!(
                "| {} | {} | {} | {} |",
                class.phrase(),
                cc.samples,
                cc.move_,
                cc.stop_observe_move
            ));
            for m in MotionLabel::ALL {
                s.push_str(&format!(
                    " {} |",
                    cc.by_motion.get(m.name()).copied().unwrap_or(0)
                ));
            }
            s.push('\n');
        }
    }
    s
}
