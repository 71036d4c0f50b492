"""Camera intrinsics as cslam-server expects them in the hello (geometry/camera.h twin).

Presets match src/geometry/camera.cpp; files are the YAML/JSON camera files that
``cslam-synth`` writes (``camera.yaml``) and ``cslam-client --camera`` reads.
"""
import os
import re
from dataclasses import dataclass, field
from typing import List

_KNOWN = {"name", "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "width", "height", "depth_factor",
          "depth_scale_correction", "readout_time"}
# Rolling-shutter readout (first to last row, seconds) of the TUM Kinect/Xtion colour cameras, as
# in src/geometry/camera.cpp.
TUM_READOUT_TIME = 0.020
_REQUIRED = {"fx", "fy", "cx", "cy", "width", "height"}


@dataclass
class Camera:
    fx: float = 525.0
    fy: float = 525.0
    cx: float = 319.5
    cy: float = 239.5
    distortion: List[float] = field(default_factory=lambda: [0.0] * 5)  # k1 k2 p1 p2 k3
    width: int = 640
    height: int = 480
    depth_factor: float = 5000.0  # raw 16-bit depth units per metre
    depth_scale_correction: float = 1.0
    name: str = "custom"
    readout_time: float = 0.0  # rolling shutter, first to last row (s); 0 = global shutter

    def validate(self):
        for key in ("fx", "fy", "depth_factor"):
            v = getattr(self, key)
            if not (v > 0) or v != v:
                raise ValueError(f"camera {self.name}: {key} must be positive, got {v}")
        if not (0 < self.width <= 8192 and 0 < self.height <= 8192):
            raise ValueError(f"camera {self.name}: size {self.width}x{self.height} out of range")
        if len(self.distortion) != 5:
            raise ValueError(f"camera {self.name}: distortion needs 5 coefficients (k1 k2 p1 p2 k3)")
        if not (0.0 <= self.readout_time <= 1.0):
            raise ValueError(f"camera {self.name}: readout_time must be in [0, 1] s, got {self.readout_time}")

    def to_wire(self, pb):
        c = pb.CameraIntrinsics(fx=self.fx, fy=self.fy, cx=self.cx, cy=self.cy, width=self.width, height=self.height,
                                depth_factor=self.depth_factor, depth_scale_correction=self.depth_scale_correction,
                                name=self.name, readout_time=self.readout_time)
        c.distortion.extend(float(d) for d in self.distortion)
        return c


def preset(name):
    """tum1 | tum2 | tum2-corrected | tum3 | synthetic (as src/geometry/camera.cpp)."""
    if name in ("tum1", "fr1"):
        return Camera(517.306408, 516.469215, 318.643040, 255.313989,
                      [0.262383, -0.953104, -0.005358, 0.002628, 1.163314], name="tum1",
                      readout_time=TUM_READOUT_TIME)
    if name in ("tum2", "fr2", "tum2-corrected"):
        return Camera(520.908620, 521.007327, 325.141442, 249.701764,
                      [0.231222, -0.784899, -0.003257, -0.000105, 0.917205],
                      depth_scale_correction=1.031 if name == "tum2-corrected" else 1.0, name=name,
                      readout_time=TUM_READOUT_TIME)
    if name in ("tum3", "fr3"):
        return Camera(535.4, 539.2, 320.1, 247.6, name="tum3", readout_time=TUM_READOUT_TIME)
    if name == "synthetic":
        c = preset("tum1")
        c.distortion = [0.0] * 5
        c.name = "synthetic"
        c.readout_time = 0.0  # the renderer exposes every row at once
        return c
    raise ValueError(f"unknown camera preset '{name}' (use tum1, tum2, tum2-corrected, tum3, synthetic or a file)")


def load_file(path):
    """A camera file (YAML/JSON, OpenCV FileStorage) as written by cslam-synth."""
    import cv2
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
    if not fs.isOpened():
        raise ValueError(f"{path}: cannot open camera file")
    root = fs.root()
    keys = set(root.keys())
    unknown = keys - _KNOWN
    if unknown:
        raise ValueError(f"{path}: unknown camera key '{sorted(unknown)[0]}'")
    missing = _REQUIRED - keys
    if missing:
        raise ValueError(f"{path}: missing camera key '{sorted(missing)[0]}'")

    def num(key, default):
        return root.getNode(key).real() if key in keys else default

    c = Camera(num("fx", 0), num("fy", 0), num("cx", 0), num("cy", 0),
               [num(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")], int(num("width", 0)), int(num("height", 0)),
               num("depth_factor", 5000.0), num("depth_scale_correction", 1.0),
               root.getNode("name").string() if "name" in keys else os.path.splitext(os.path.basename(path))[0],
               num("readout_time", 0.0))
    fs.release()
    c.validate()
    return c


def preset_from_name(path):
    """'tum1' | 'tum2' | 'tum3' when the last or second-to-last part of `path` names a TUM camera
    (freiburg1..3 or fr1..3 as a word: rgbd_dataset_freiburg2_xyz.bag, tum_fr1_desk), else ''
    (the rule of src/io/dataset_camera.cpp)."""
    parts = [q for q in os.path.normpath(path).split(os.sep) if q][-2:] if path else []
    for part in reversed(parts):
        m = re.search(r"(?<![a-z0-9])(?:freiburg|fr)([123])(?![0-9])", part.lower())
        if m:
            return "tum" + m.group(1)
    return ""


def load(preset_or_path):
    """A file if the path exists, else a preset name (like cslam-client --camera)."""
    return load_file(preset_or_path) if os.path.exists(preset_or_path) else preset(preset_or_path)
