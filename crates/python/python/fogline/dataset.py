"""DriveLM-Deficit from Python: build the data set, import your own logs, score a backend.

    >>> import fogline.dataset
    >>> built = fogline.dataset.build_deficit("deficit", samples=40, seed=7)   # doctest: +SKIP
    >>> ev = fogline.dataset.evaluate("deficit", backend="rules", split="all")  # doctest: +SKIP
    >>> ev.by_class["pedestrian"]["object"]["value"]                           # doctest: +SKIP
    1.0

The same jobs as ``fogline dataset deficit``, ``fogline dataset import`` and ``fogline rco
eval`` (the library's ``fogline_api::dataset``), with the same files and bytes: five-frame
samples on the RCO's three views with a traffic light, sign, pedestrian or bicycle hidden
behind a deficit, the expert's labels, the LLaMA-Factory and DriveLM exports; and the
figure-6 evaluation (hazard inference and planning prompts, per hidden class, motion label and
strategy, with 95 % Wilson intervals), written as ``eval.json``, ``eval.md`` and
``report.html``. The formats are in ``docs/dataset.md``. The GIL is released while a job runs.
"""

import json
from pathlib import Path

from ._fogline import dataset_deficit as _deficit
from ._fogline import dataset_evaluate as _evaluate
from ._fogline import dataset_import as _import

__all__ = ["build_deficit", "import_logs", "evaluate", "Built", "Evaluation", "GALLERY"]

GALLERY = 8
"""Samples in ``report.html``'s gallery by default."""


def _split(split, what="split"):
    try:
        shares = [float(x) for x in split]
    except (TypeError, ValueError):
        raise TypeError(f"{what}: expected three shares (train, val, test), got {split!r}") from None
    if len(shares) != 3:
        raise ValueError(f"{what}: expected three shares (train, val, test), got {len(shares)}")
    return shares


def _image(image):
    if image not in ("png", "jpeg"):
        raise ValueError(f"image: expected 'png' or 'jpeg', got {image!r}")
    return image


class Built:
    """What a build or an import wrote.

    Attributes:
        dir: the data set directory (a ``Path``).
        samples: samples written.
        counts: per split (``train``, ``val``, ``test``) and ``all``: samples per class with
            ``move`` / ``stop-observe-move`` and motion (figure 5b), as a dict.
        threads, samples_s, elapsed_s: worker threads, the samples' and the whole wall time.
        files: the files besides the images (``Path``s).
        summary: what the CLI prints.
        data: the whole summary as a dict.
    """

    def __init__(self, data, summary):
        self.data = data
        self.summary = summary
        self.dir = Path(data["dir"])
        self.samples = int(data["samples"])
        self.counts = data["counts"]
        self.threads = int(data["threads"])
        self.samples_s = float(data["samples_s"])
        self.elapsed_s = float(data["elapsed_s"])
        self.files = [self.dir / f for f in data["files"]]

    def __repr__(self):
        return f"Built({str(self.dir)!r}, samples={self.samples}, {self.elapsed_s:.1f} s)"


def build_deficit(out, samples=1000, seed=0, *, clips_per_town=4, split=(0.8, 0.1, 0.1),
                  image="png", jpeg_quality=90, threads=0):
    """Build DriveLM-Deficit from fogline's world into ``out`` (``fogline dataset deficit``).

    Args:
        out: the output directory (replaced as a whole at the end; an interrupted build
            leaves it as it was).
        samples: how many samples.
        seed: the seed; the same seed gives the same bytes, on any number of threads.
        clips_per_town: clips per town (a town sits in one split only).
        split: the towns' shares in train, val and test (sum 1).
        image: ``"png"`` or ``"jpeg"`` frames.
        jpeg_quality: the JPEG quality (1-100) with ``image="jpeg"``.
        threads: worker threads (0: all cores).

    Returns:
        :class:`Built`.

    Raises:
        ValueError: an invalid setting (the message names it).
        OSError: ``out`` cannot be written.
    """
    params = {"samples": int(samples), "seed": int(seed), "clips_per_town": int(clips_per_town),
              "split_fractions": _split(split), "image": _image(image),
              "jpeg_quality": int(jpeg_quality), "threads": int(threads)}
    data, summary = _deficit(str(out), json.dumps(params))
    return Built(json.loads(data), summary)


def import_logs(logs, out, *, seed=0, stride=5, split=(0.8, 0.1, 0.1), image="png",
                jpeg_quality=90):
    """Samples from your own logs (``fogline dataset import``): ``logs/<log>/log.json`` with
    per-frame images, boxes and the expert's brake state (the layout is in
    ``docs/dataset.md``); a log is a town.

    Raises:
        ValueError: a log does not follow the layout (the message names the file, frame and
            field), or an invalid setting.
        OSError: a file cannot be read or ``out`` cannot be written.
    """
    params = {"seed": int(seed), "stride_frames": int(stride), "split_fractions": _split(split),
              "image": _image(image), "jpeg_quality": int(jpeg_quality)}
    data, summary = _import(str(logs), str(out), json.dumps(params))
    return Built(json.loads(data), summary)


class Evaluation:
    """A backend's figure-6 scores on a data set (``eval.json``).

    Every proportion is a dict ``{"hits", "n", "value", "ci_low", "ci_high"}`` (``value``
    and the 95 % Wilson interval ``None`` for an empty cell).

    Attributes:
        backend, split, samples: who answered, on which split, how many samples.
        overall: the row of all samples: ``object``, ``motion``, ``strategy`` (hazard
            inference), ``move_recall``, ``som_recall``, ``invalid``, and the planning
            prompt's ``plan_strategy``, ``plan_move_recall``, ``plan_som_recall``,
            ``plan_invalid``.
        by_class: ``{"traffic_light" | "traffic_sign" | "pedestrian" | "bicycle": row}``.
        by_motion: ``{"crossing" | "oncoming" | "leading" | "static": row}``.
        by_strategy: ``{"move" | "stop-observe-move": row}``.
        latency: ``{prompt: {"calls", "mean_ms", "ci_low_ms", "ci_high_ms", "p50_ms",
            "p95_ms", "max_ms"}}`` for ``hazard_inference``, ``move_plan`` and
            ``stop_observe_move_plan``.
        answers: every sample's truth and answers (list of dicts, sample order).
        markdown: the tables as ``eval.md`` holds them.
        files: ``eval.json``, ``eval.md``, ``report.html`` (``Path``s).
        data: the whole ``eval.json`` as a dict.
    """

    def __init__(self, data, markdown, files):
        self.data = data
        self.markdown = markdown
        self.files = [Path(f) for f in files]
        self.backend = data["backend"]
        self.split = data["split"]
        self.samples = int(data["samples"])
        self.overall = data["overall"]
        self.by_class = {r["group"]: r for r in data["by_class"]}
        self.by_motion = {r["group"]: r for r in data["by_motion"]}
        self.by_strategy = {r["group"]: r for r in data["by_strategy"]}
        self.latency = {"hazard_inference": data["latency"]}
        self.latency.update({p["prompt"]: p["latency"] for p in data.get("plan_latency", [])})
        self.answers = data["answers"]

    def __repr__(self):
        o = self.overall
        pct = lambda r: "–" if r["value"] is None else f"{100 * r['value']:.1f}%"  # noqa: E731
        return (f"Evaluation({self.backend!r}, split={self.split!r}, samples={self.samples}, "
                f"object={pct(o['object'])}, strategy={pct(o['strategy'])}, "
                f"plan_strategy={pct(o['plan_strategy'])})")


def evaluate(data_dir, backend="rules", *, split="test", limit=None, jobs=1, out=None,
             gallery=GALLERY, url=None, model=None, api_key_env=None, timeout_ms=None,
             send_images=None):
    """Score a backend on a data set (``fogline rco eval``): every sample goes through the
    controller's own hazard inference prompt and then its planning prompt for the strategy
    chosen, each answer through the controller's own validation; a failed call or a rejected
    answer is counted as invalid, never raised.

    Args:
        data_dir: the data set (``build_deficit``'s ``out``).
        backend: ``"rules"`` (offline) or ``"openai"`` (any OpenAI-compatible server).
        split: ``"train"``, ``"val"``, ``"test"`` or ``"all"``.
        limit: at most this many samples (the first of the split).
        jobs: concurrent calls (one backend each).
        out: where ``eval.json``, ``eval.md`` and ``report.html`` go (default
            ``data_dir/eval``), written as one set.
        gallery: samples shown with their frames and answers in ``report.html``.
        url, model, api_key_env, timeout_ms, send_images: the ``openai`` backend's settings
            (the key is read from the environment variable, never passed).

    Returns:
        :class:`Evaluation`.

    Raises:
        ValueError: an invalid setting, or a data set that does not read (the message names
            the file and field).
        OSError: a file cannot be read or written.
    """
    openai = {k: v for k, v in {"base_url": url, "model": model, "api_key_env": api_key_env,
                                "timeout_ms": timeout_ms, "send_images": send_images}.items()
              if v is not None}
    if backend != "openai" and openai:
        raise ValueError(f"{', '.join(openai)}: settings of the openai backend, not of {backend!r}")
    data, markdown, files = _evaluate(
        str(data_dir), split=str(split), limit=None if limit is None else int(limit),
        jobs=int(jobs), backend=str(backend), openai=json.dumps(openai),
        out=None if out is None else str(out), gallery=int(gallery))
    return Evaluation(json.loads(data), markdown, files)
