#!/usr/bin/env python3
"""How far the floor's band moves along an image row at a roll, against its width: what labelling rolled rows by
value would face (docs/performance.md, "A pose with roll").

A row without roll has one rise, so one predicted floor depth and one band of floor values (the threshold t(d) on
either side): two value thresholds label it. With roll the floor's depth moves along the row; where it moves by more
than the band is wide, no pair of thresholds fits the whole row, and the values between the two ends' thresholds
would be labelled pixel by pixel. Per floor row of the bench's pose (Kinect v2 512x424, 1.1 m, pitched 15 deg, the
default threshold curve), the predicted floor depth at the row's two ends, their difference over 2 t(d):

    bench/roll_band.py [--rolls DEG,...]
"""

import argparse

import numpy as np

import kinect_pipeline as kp


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rolls", default="0.05,0.2,0.5,1,2,5", help="rolls [deg], comma-separated")
    rolls = [float(r) for r in ap.parse_args().rolls.split(",")]
    cam = kp.Camera(512, 424, 365.5, 365.5, 255.5, 211.5)
    curve = kp.default_threshold_curve()
    print("| roll [deg] | floor rows | median shift / band | rows under 0.5 | rows under 1 |")
    print("|---|---|---|---|---|")
    for roll in rolls:
        cfg = kp.Config(sensor_height=1.1, sensor_pitch=np.radians(15.0), sensor_roll=np.radians(roll), max_depth=8.0,
                        refine_floor=False)  # fmt: skip
        pipe = kp.Pipeline(cam, cfg)
        pipe.process(np.zeros((424, 512), np.uint16))
        floor = pipe.predicted_floor()
        ends = floor[:, [0, -1]]
        rows = np.all(np.isfinite(ends) & (ends > 0) & (ends < cfg.max_depth), axis=1)
        a, b = ends[rows, 0], ends[rows, 1]
        band = 2.0 * kp.evaluate_curve(curve, 0.5 * (a + b))
        shift = np.abs(a - b) / band
        print(f"| {roll:g} | {rows.sum()} | {np.median(shift):.2f} | {100 * np.mean(shift < 0.5):.0f} % | "
              f"{100 * np.mean(shift < 1):.0f} % |")  # fmt: skip


if __name__ == "__main__":
    main()
