"""The ``lsadphoto`` command.

Every error lsadphoto raises on purpose becomes one line on stderr and a non-zero exit code
(2 for bad input); warnings are one line each. ``--debug`` shows tracebacks.
"""

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

from ._version import __version__
from .errors import BadInputError, LsadError

PROG = "lsadphoto"


def _warning_line(message, category, filename, lineno, file=None, line=None):
    print(f"{PROG}: warning: {message}", file=sys.stderr)


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def _print_json(record):
    print(json.dumps(record, indent=2, default=_json_default))


def _load_profile(path):
    from .calibrate.profile import load_profile

    return load_profile(path) if path else None


def cmd_luminance(args):
    from .calibrate.spot import SpotReading
    from .io import atomic_outputs, write_exr, write_false_colour_png, write_hdr
    from .luminance import luminance_from_raw
    from .raw.decode import read_dark_frame

    angle = np.deg2rad(args.acceptance_angle_deg)
    spots = [SpotReading.parse(s, acceptance_angle=angle) for s in args.spot or []]
    outputs = {"exr": Path(args.output)}
    if outputs["exr"].suffix.lower() != ".exr":
        raise BadInputError(f"output {args.output} must end in .exr")
    if args.hdr:
        outputs["hdr"] = Path(args.hdr)
    if args.png:
        outputs["png"] = Path(args.png)
    dark = read_dark_frame(args.dark_frame) if args.dark_frame else None
    result = luminance_from_raw(
        args.raw, spots=spots, profile=_load_profile(args.profile), demosaic=args.demosaic,
        colour_method=args.colour_method, dark_frame=dark,
    )
    writers = {"exr": write_exr, "hdr": write_hdr, "png": write_false_colour_png}
    with atomic_outputs(*outputs.values()) as temps:
        for (kind, _), temp in zip(outputs.items(), temps):
            writers[kind](result.map, temp)
    summary = dict(result.summary, outputs={k: str(v) for k, v in outputs.items()})
    if args.json:
        _print_json(summary)
    else:
        flag = "" if summary["calibrated"] else " (uncalibrated)"
        print(
            f"wrote {outputs['exr']}: calibration factor {summary['calibration_factor']:.6g} "
            f"± {100 * summary['calibration_uncertainty']:.1f} %{flag}, "
            f"saturated {100 * summary['saturated_fraction']:.2f} %"
        )
    return 0


def cmd_calibrate_vignetting(args):
    from .calibrate.profile import CameraProfile, save_profile
    from .calibrate.vignetting import fit_vignetting_polynomial
    from .raw.decode import decode_raw

    frames = [decode_raw(p, demosaic=args.demosaic) for p in args.flat]
    shape = frames[0].sensor_shape
    for f in frames[1:]:
        if f.sensor_shape != shape:
            raise BadInputError(f"flat-field frames differ in size: {f.path} is {f.sensor_shape}, not {shape}")
    rgb = np.mean([f.rgb for f in frames], axis=0)
    saturated = np.any([f.saturated.any(axis=-1) for f in frames], axis=0)
    model = fit_vignetting_polynomial(rgb.sum(axis=-1), shape, binning=frames[0].binning,
                                      degree=args.degree, saturated=saturated)
    profile = _load_profile(args.profile) or CameraProfile(id=args.id or "vignetting-fit")
    profile.vignetting = model
    profile.provenance = dict(profile.provenance, vignetting_fit=f"lsadphoto {__version__} from "
                              + ", ".join(Path(p).name for p in args.flat))
    save_profile(profile, args.output)
    record = {"output": args.output, "coefficients": model.coefficients, "rms_residual": model.rms_residual,
              "frames": [str(p) for p in args.flat]}
    if args.json:
        _print_json(record)
    else:
        coeffs = ", ".join(f"{c:.5g}" for c in model.coefficients)
        print(f"wrote {args.output}: V = 1 + Σ a_k r^2k with a = [{coeffs}], RMS residual "
              f"{100 * model.rms_residual:.2f} %")
    return 0


def cmd_calibrate_geometry(args):
    from .calibrate.geometric import calibrate_geometry, parse_pattern
    from .calibrate.profile import CameraProfile, save_profile

    result = calibrate_geometry(args.images, pattern=parse_pattern(args.pattern), model=args.model)
    profile = _load_profile(args.profile) or CameraProfile(id=args.id or "geometry-fit")
    profile.lens_projection = result.projection
    profile.width, profile.height = result.width, result.height
    profile.provenance = dict(profile.provenance, geometry_fit=(
        f"lsadphoto {__version__}: {args.model} model, pattern {args.pattern}, RMS {result.rms_px:.3f} px, "
        f"{len(result.summary()['used_images'])} views"))
    save_profile(profile, args.output)
    summary = dict(result.summary(), output=args.output)
    if args.json:
        _print_json(summary)
    else:
        print(f"wrote {args.output}: {args.model} model, RMS {result.rms_px:.3f} px, "
              f"{len(summary['used_images'])} views used, {len(summary['rejected_images'])} rejected")
        for item in summary["rejected_images"]:
            print(f"  rejected {item['name']}: {item['reason']}")
    return 0


def build_parser():
    from .raw.colour import COLOUR_METHODS
    from .raw.decode import DEMOSAIC_METHODS

    parser = argparse.ArgumentParser(prog=PROG, description="Calibrated luminance maps from RAW photographs.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of errors")
    sub = parser.add_subparsers(dest="command", required=True)

    lum = sub.add_parser("luminance", help="RAW file(s) of one view → absolute luminance map")
    lum.add_argument("raw", nargs="+", help="RAW file, or several forming an exposure bracket")
    lum.add_argument("--spot", action="append", metavar="ROW,COL,CD_M2",
                     help="spot-meter reading at a full-resolution pixel (repeatable)")
    lum.add_argument("--acceptance-angle-deg", type=float, default=1.0,
                     help="spot meter acceptance angle, full cone [deg] (LS-100: 1)")
    lum.add_argument("--profile", help="camera profile (TOML)")
    lum.add_argument("--demosaic", choices=DEMOSAIC_METHODS, default="superpixel")
    lum.add_argument("--colour-method", choices=COLOUR_METHODS, default="auto")
    lum.add_argument("--dark-frame", action="append", metavar="RAW", help="dark frame(s) for a black-level map")
    lum.add_argument("-o", "--output", required=True, help="output OpenEXR map (.exr)")
    lum.add_argument("--hdr", help="also write a Radiance HDR map")
    lum.add_argument("--png", help="also write a false-colour PNG")
    lum.add_argument("--json", action="store_true", help="print a JSON summary")
    lum.set_defaults(func=cmd_luminance)

    cal = sub.add_parser("calibrate", help="camera calibration")
    calsub = cal.add_subparsers(dest="what", required=True)
    vig = calsub.add_parser("vignetting", help="fit a vignetting polynomial from flat-field RAW frames")
    vig.add_argument("flat", nargs="+", help="flat-field RAW frames (uniform diffuse field, same settings)")
    vig.add_argument("-o", "--output", required=True, help="camera profile to write (TOML)")
    vig.add_argument("--profile", help="profile to start from (its other sections are kept)")
    vig.add_argument("--id", help="profile id when no --profile is given")
    vig.add_argument("--degree", type=int, default=3, help="number of even polynomial terms")
    vig.add_argument("--demosaic", choices=DEMOSAIC_METHODS, default="superpixel")
    vig.add_argument("--json", action="store_true")
    vig.set_defaults(func=cmd_calibrate_vignetting)
    geo = calsub.add_parser("geometry", help="calibrate the camera geometry from chessboard images (OpenCV)")
    geo.add_argument("images", nargs="+", help="images of a chessboard (8-bit, any format OpenCV reads)")
    geo.add_argument("--pattern", required=True, metavar="chessboard:COLSxROWS:SQUARE_MM",
                     help="inner corners per row and column, and the square size [mm]")
    geo.add_argument("--model", choices=("pinhole", "fisheye"), default="pinhole")
    geo.add_argument("-o", "--output", required=True, help="camera profile to write (TOML)")
    geo.add_argument("--profile", help="profile to start from (its other sections are kept)")
    geo.add_argument("--id", help="profile id when no --profile is given")
    geo.add_argument("--json", action="store_true")
    geo.set_defaults(func=cmd_calibrate_geometry)
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    warnings.showwarning = _warning_line
    try:
        return args.func(args)
    except LsadError as exc:
        if args.debug:
            raise
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print(f"{PROG}: error: out of memory", file=sys.stderr)
        return 1
    except Exception as exc:  # last resort: one line, never a traceback
        if args.debug:
            raise
        print(f"{PROG}: internal error: {type(exc).__name__}: {exc} (rerun with --debug and report it)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
