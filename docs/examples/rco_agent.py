"""A CARLA leaderboard-style agent that hands control to fogline's LLM-RCO controller.

Drop-in shape of a CARLA leaderboard ``AutonomousAgent``: ``sensors()`` declares three RGB
cameras as the LLM-RCO paper mounts them, and ``run_step(input_data, timestamp)`` turns the
camera images (CARLA delivers BGRA) and the perception-deficit regions into a
``carla.VehicleControl`` (a dict outside CARLA). Where the deficit masks come from is up to
you: here ``deficits_for(camera, image)`` finds them in the pixels as the LLM-RCO paper
draws them (black fill, red outline); replace it with your perception's lost-region masks.

Run outside CARLA (as docs/python.md's test does) with fake sensor data:

    python docs/examples/rco_agent.py
"""

import numpy as np

import fogline.rco

CAMERAS = {  # sensor id -> fogline camera, with the paper's mounting
    "left": ("cross_left", -60.0),
    "front": ("front_wide", 0.0),
    "right": ("cross_right", 60.0),
}
WIDTH, HEIGHT = 576, 320


def deficits_for(camera, rgb):
    """The regions of ``rgb`` hidden behind a black box with a red outline (a boolean mask).

    A stand-in for your perception's own lost-pixel masks: black pixels count when a
    saturated red pixel lies within a few pixels of them on their row.
    """
    black = rgb.max(axis=2) < 12
    red = (rgb[..., 0] > 200) & (rgb[..., 1] < 60) & (rgb[..., 2] < 60)
    near_red = np.zeros_like(red)
    for shift in range(1, 40):
        near_red[:, shift:] |= red[:, :-shift]
        near_red[:, :-shift] |= red[:, shift:]
    return black & near_red


class RcoAgent:
    """``setup``, ``sensors`` and ``run_step`` as the CARLA leaderboard calls them."""

    def setup(self, path_to_conf_file=None):
        self.controller = fogline.rco.Controller(backend="rules")
        self.route_direction = "follow_lane"

    def sensors(self):
        return [
            {"type": "sensor.camera.rgb", "id": sid, "x": 1.3, "y": 0.0, "z": 2.3,
             "roll": 0.0, "pitch": 0.0, "yaw": yaw, "width": WIDTH, "height": HEIGHT, "fov": 120}
            for sid, (_, yaw) in CAMERAS.items()
        ] + [{"type": "sensor.speedometer", "id": "speed"}]

    def run_step(self, input_data, timestamp):
        frames, deficits = {}, {}
        for sid, (camera, _) in CAMERAS.items():
            _, bgra = input_data[sid]
            rgb = np.ascontiguousarray(bgra[..., 2::-1])  # BGRA -> RGB
            frames[camera] = rgb
            deficits[camera] = deficits_for(camera, rgb)
        speed = float(input_data["speed"][1]["speed"])
        decision = self.controller.step(frames, deficits, speed, direction=self.route_direction)
        return decision.carla_control()


def fake_input(tick, hidden):
    """CARLA-shaped sensor data: grey road images, a masked pedestrian ahead when ``hidden``."""
    data = {}
    for sid in CAMERAS:
        bgra = np.full((HEIGHT, WIDTH, 4), 110, np.uint8)
        if sid == "front" and hidden:
            bgra[140:220, 300:340, :3] = 0
            bgra[138:140, 298:342, :3] = (0, 0, 255)  # red outline (BGR)
            bgra[220:222, 298:342, :3] = (0, 0, 255)
            bgra[138:222, 298:300, :3] = (0, 0, 255)
            bgra[138:222, 340:342, :3] = (0, 0, 255)
        data[sid] = (tick, bgra)
    data["speed"] = (tick, {"speed": 5.0})
    return data


if __name__ == "__main__":
    agent = RcoAgent()
    agent.setup()
    for tick in range(25):
        control = agent.run_step(fake_input(tick, hidden=5 <= tick < 15), tick * 0.1)
        print(tick, control)
