#!/usr/bin/env python3
"""Depth-to-depth consistency of consecutive frames against the assumed capture time of the depth
images: each frame's depth image is placed with the trajectory interpolated at
t_rgb + alpha * (t_depth - t_rgb), its pixels (every 6th) are projected into the next frame's depth
image, and the median |depth difference| per frame pair is taken. alpha = 1 assumes the listed depth
stamps, alpha = 0 the colour image's stamp. The alpha with the smallest difference is the one the
data supports. Needs Debian's python3-numpy and python3-opencv.

  scripts/depth-time-consistency.py DATASET TRAJECTORY.txt [--alphas -0.5,0,0.5,1,1.5] [--step 2]
    [--camera fx,fy,cx,cy,k1,k2,p1,p2,k3] [--depth-factor 5000]
TRAJECTORY: TUM format at the colour images' stamps (e.g. cslam-slam --out). Default camera: TUM fr1.
"""
import argparse
import os

import cv2
import numpy as np


def read_list(path):
    out = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            t, name = line.split()[:2]
            out.append((float(t), name))
    return out


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def slerp(q0, q1, s):
    d = float(np.dot(q0, q1))
    if d < 0:
        q1, d = -q1, -d
    if d > 0.9995:
        q = q0 + s * (q1 - q0)
        return q / np.linalg.norm(q)
    th = np.arccos(d)
    return (np.sin((1 - s) * th) * q0 + np.sin(s * th) * q1) / np.sin(th)


def pose_at(traj, t, max_gap=0.1):
    """T_world_cam (4x4) interpolated at t, or None outside the trajectory or across a gap."""
    i = int(np.searchsorted(traj[:, 0], t))
    if i <= 0 or i >= len(traj):
        return None
    a, b = traj[i - 1], traj[i]
    if b[0] - a[0] > max_gap:
        return None
    s = (t - a[0]) / (b[0] - a[0])
    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(slerp(a[4:8], b[4:8], s))
    m[:3, 3] = a[1:4] + s * (b[1:4] - a[1:4])
    return m


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("dataset")
    p.add_argument("trajectory")
    p.add_argument("--alphas", default="-0.5,0,0.5,1,1.5")
    p.add_argument("--step", type=int, default=2, help="every step-th frame pair")
    p.add_argument("--camera", default="517.306408,516.469215,318.643040,255.313989,0.262383,-0.953104,-0.005358,0.002628,1.163314")
    p.add_argument("--depth-factor", type=float, default=5000.0)
    a = p.parse_args()
    c = [float(v) for v in a.camera.split(",")]
    K = np.array([[c[0], 0, c[2]], [0, c[1], c[3]], [0, 0, 1]])
    dist = np.array(c[4:9])
    rgb, depth = read_list(os.path.join(a.dataset, "rgb.txt")), read_list(os.path.join(a.dataset, "depth.txt"))
    depth_t = np.array([t for t, _ in depth])
    traj = np.loadtxt(a.trajectory)
    traj = traj[np.argsort(traj[:, 0])]
    frames = []  # (t_rgb, t_depth, depth file): every colour frame with the nearest depth within 20 ms
    for t, _ in rgb:
        j = int(np.argmin(np.abs(depth_t - t)))
        if abs(depth_t[j] - t) <= 0.02:
            frames.append((t, depth_t[j], depth[j][1]))
    h, w = cv2.imread(os.path.join(a.dataset, frames[0][2]), cv2.IMREAD_ANYDEPTH).shape
    ys, xs = np.mgrid[4:h - 4:6, 4:w - 4:6]
    pix = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    rays = cv2.undistortPoints(pix.reshape(-1, 1, 2), K, dist).reshape(-1, 2)
    cache = {}

    def load(name):
        if name not in cache:
            cache[name] = cv2.imread(os.path.join(a.dataset, name), cv2.IMREAD_ANYDEPTH).astype(np.float64) / a.depth_factor
        return cache[name]

    alphas = [float(v) for v in a.alphas.split(",")]
    res = {al: [] for al in alphas}
    for k in range(0, len(frames) - 1, a.step):
        (t0, d0, f0), (t1, d1, f1) = frames[k], frames[k + 1]
        if f0 == f1:
            continue  # one depth image serving two colour frames
        D0, D1 = load(f0), load(f1)
        z0 = D0[pix[:, 1].astype(int), pix[:, 0].astype(int)]
        ok = z0 > 0.3
        X = np.stack([rays[ok, 0] * z0[ok], rays[ok, 1] * z0[ok], z0[ok]], 1)
        for al in alphas:
            P0, P1 = pose_at(traj, t0 + al * (d0 - t0)), pose_at(traj, t1 + al * (d1 - t1))
            if P0 is None or P1 is None:
                continue
            M = np.linalg.inv(P1) @ P0
            Y = X @ M[:3, :3].T + M[:3, 3]
            pp = cv2.projectPoints(Y, np.zeros(3), np.zeros(3), K, dist)[0].reshape(-1, 2)
            u, v = np.round(pp[:, 0]).astype(int), np.round(pp[:, 1]).astype(int)
            inside = (u >= 0) & (u < w) & (v >= 0) & (v < h) & (Y[:, 2] > 0.3)
            zm = D1[v[inside], u[inside]]
            e = np.abs(zm - Y[inside, 2])
            good = (zm > 0) & (e < 0.1)
            if good.sum() > 100:
                res[al].append(np.median(e[good]))
    for al in alphas:
        r = np.array(res[al])
        print(f"alpha {al:5.2f}: median |dz| per frame pair: median {np.median(r) * 1000:.2f} mm, "
              f"mean {np.mean(r) * 1000:.2f} mm over {len(r)} pairs")


if __name__ == "__main__":
    main()
