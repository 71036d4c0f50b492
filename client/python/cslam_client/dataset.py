"""TUM RGB-D folders (rgb.txt, depth.txt, images) as src/io/tum_dataset.cpp reads them."""
import os
from dataclasses import dataclass


@dataclass
class RgbdPair:
    rgb_time: float
    depth_time: float
    rgb_path: str
    depth_path: str


def _read_list(root, name):
    path = os.path.join(root, name)
    out = []
    with open(path) as f:
        for line_no, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            tok = line.split()
            if len(tok) != 2:
                raise ValueError(f"{path}:{line_no}: expected 'timestamp path', got {len(tok)} values")
            t = float(tok[0])
            if out and t <= out[-1][0]:
                raise ValueError(f"{path}:{line_no}: timestamps must increase")
            out.append((t, os.path.join(root, tok[1])))
    return out


def associate(a, b, max_dt=0.02):
    """Index pairs (i, j) with |a[i] - b[j]| <= max_dt, greedy by smallest difference (TUM associate.py)."""
    cands = []
    start = 0
    for i, ta in enumerate(a):
        while start < len(b) and b[start] < ta - max_dt:
            start += 1
        j = start
        while j < len(b) and b[j] <= ta + max_dt:
            cands.append((abs(ta - b[j]), i, j))
            j += 1
    cands.sort()
    used_a, used_b, out = set(), set(), []
    for _, i, j in cands:
        if i in used_a or j in used_b:
            continue
        used_a.add(i)
        used_b.add(j)
        out.append((i, j))
    return sorted(out)


def open_tum(root, max_dt=0.02):
    rgb = _read_list(root, "rgb.txt")
    depth = _read_list(root, "depth.txt")
    return [RgbdPair(rgb[i][0], depth[j][0], rgb[i][1], depth[j][1])
            for i, j in associate([t for t, _ in rgb], [t for t, _ in depth], max_dt)]


def load_pair(pair):
    """(bgr uint8 HxWx3, depth uint16 HxW) of a pair."""
    import cv2
    bgr = cv2.imread(pair.rgb_path, cv2.IMREAD_COLOR)
    if bgr is None:
        raise ValueError(f"{pair.rgb_path}: cannot read RGB image")
    depth = cv2.imread(pair.depth_path, cv2.IMREAD_ANYDEPTH)
    if depth is None or depth.dtype.name != "uint16":
        raise ValueError(f"{pair.depth_path}: cannot read a 16-bit depth image")
    return bgr, depth
