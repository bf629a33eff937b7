"""Reads a PhysicalAI-AV tree with the dataset's own devkit (the PyPI package physical-ai-av)
the way Alpamayo R1's loader does (NVlabs/alpamayo, src/alpamayo_r1/load_physical_aiavdataset.py,
without torch), for the import test in import_cmd.rs to compare with fogline's import.

    python physicalai_devkit.py ROOT OUT '{"clips": [...], "t0_us": [...], "cameras": [...]}'

The devkit reads through a Hugging Face cache: ROOT is linked in as the snapshot of a made-up
revision of nvidia/PhysicalAI-Autonomous-Vehicles in a temporary cache, offline. It writes
OUT/devkit.json (per clip and t0: the ego history as [x, y, yaw, speed] rows, the 64 future
waypoints [x, y], and per camera the file of the four frames, their shape and timestamps) and
the frames as raw RGB (N, H, W, 3) uint8 files.
"""

import json
import os
import pathlib
import sys
import tempfile

root, out, spec = sys.argv[1], pathlib.Path(sys.argv[2]), json.loads(sys.argv[3])
home = tempfile.mkdtemp(prefix="fogline-devkit-")
os.environ["HF_HUB_OFFLINE"] = "1"
os.environ["HF_HOME"] = home

import numpy as np  # noqa: E402
import physical_ai_av  # noqa: E402
import scipy.spatial.transform as spt  # noqa: E402

REVISION = "0" * 40
snapshots = pathlib.Path(home) / "hub" / "datasets--nvidia--PhysicalAI-Autonomous-Vehicles" / "snapshots"
snapshots.mkdir(parents=True)
(snapshots / REVISION).symlink_to(os.path.abspath(root))
avdi = physical_ai_av.PhysicalAIAVDatasetInterface(
    revision=REVISION, cache_dir=str(pathlib.Path(home) / "hub"), token=False
)

result = {}
for clip in spec["clips"]:
    egomotion = avdi.get_clip_feature(clip, avdi.features.LABELS.EGOMOTION)
    for t0 in spec["t0_us"]:
        history_ts = t0 + np.arange(-15, 1, dtype=np.int64) * 100_000
        future_ts = t0 + np.arange(1, 65, dtype=np.int64) * 100_000
        history = egomotion(history_ts)
        future = egomotion(future_ts)
        t0_xyz = history.pose.translation[-1].copy()
        t0_rot = spt.Rotation.from_quat(history.pose.rotation.as_quat()[-1].copy())
        inv = t0_rot.inv()
        history_xyz = inv.apply(history.pose.translation - t0_xyz)
        future_xyz = inv.apply(future.pose.translation - t0_xyz)
        history_rot = (inv * spt.Rotation.from_quat(history.pose.rotation.as_quat())).as_matrix()
        yaw = np.arctan2(history_rot[:, 1, 0], history_rot[:, 0, 0])
        speed = np.linalg.norm(history.velocity, axis=1)
        entry = {
            "history": np.column_stack([history_xyz[:, :2], yaw, speed]).tolist(),
            "future": future_xyz[:, :2].tolist(),
            "frames": {},
        }
        image_ts = np.array([t0 - (3 - i) * 100_000 for i in range(4)], dtype=np.int64)
        for camera in spec["cameras"]:
            reader = avdi.get_clip_feature(clip, camera)
            frames, frame_ts = reader.decode_images_from_timestamps(image_ts)
            reader.close()
            name = f"{clip}_{t0}_{camera}.rgb"
            (out / name).write_bytes(np.ascontiguousarray(frames, dtype=np.uint8).tobytes())
            entry["frames"][camera] = {
                "file": name,
                "shape": list(frames.shape),
                "timestamps": frame_ts.tolist(),
            }
        result[f"{clip}@{t0}"] = entry

(out / "devkit.json").write_text(json.dumps(result))
print(f"devkit {physical_ai_av.__version__}: {len(result)} clip times read")
