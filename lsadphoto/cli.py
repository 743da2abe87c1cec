"""The ``lsadphoto`` command.

Every error lsadphoto raises on purpose becomes one line on stderr and a non-zero exit code
(2 for bad input); warnings are one line each. ``--debug`` shows tracebacks.
"""

import argparse
import gc
import json
import math
import os
import sys
import warnings
from pathlib import Path

# ``lsadphoto score`` does no linear algebra that BLAS threads speed up, and OpenBLAS starting
# its thread pool as numpy loads costs a score process 0.07 s of CPU and up to 0.1 s of wall
# time (docs/performance.md, "Latency of a whole score process"): one BLAS thread there,
# unless the user chose a number (the variables OpenBLAS reads). Only the console script
# reaches this line before numpy is loaded.
if sys.argv[1:2] == ["score"] and not any(
        name in os.environ for name in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")):
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
# numpy advises the kernel to back arrays of 4 MB and more with transparent huge pages. On a
# virtual machine whose host backs guest memory on first touch, a fresh 2 MB page costs far
# more than the 512 small pages the guest reuses (the 2-core VM of docs/performance.md,
# "Small pages": 1.15 GB of new arrays 2.1–3.6 s of system time with huge pages, 0.54–0.57 s
# without; a 24 MP score process 2.4–3.7 → 1.4–2.4 s), while the few huge pages a small
# picture needs come back warm from the processes before (786²: small pages 0.015 s more of
# CPU). So ``score`` asks for small pages when its largest input file has
# ``_SMALL_PAGES_MIN_BYTES`` or more (a 1572² Radiance picture has 10 MB), unless the user set
# numpy's own variable (read as numpy loads).
_SMALL_PAGES_MIN_BYTES = 8 << 20


def _largest_file(paths):
    """Size [bytes] of the largest existing file among ``paths`` (0 where none is)."""
    return max((os.path.getsize(p) for p in paths if os.path.isfile(p)), default=0)


if sys.argv[1:2] == ["score"] and _largest_file(sys.argv[2:]) >= _SMALL_PAGES_MIN_BYTES:
    os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")

import numpy as np  # noqa: E402 (after the BLAS thread and huge-page settings)

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


def _json_text(record):
    return json.dumps(record, indent=2, default=_json_default)


def _print_json(record):
    print(_json_text(record))


class _Choices:
    """Valid values of an option, defined in the library (``module.name``) and imported only
    when argparse checks a value or prints help, so that ``lsadphoto`` starts fast.

    ``add_argument`` formats every option's choices once to check its metavar: while
    :func:`build_parser` runs (``building``) they are empty, otherwise building the parser
    would import every command's modules (the study's SciPy, the solver) in every process.
    """

    building = False

    def __init__(self, module, name):
        self.module, self.name = module, name

    def _values(self):
        import importlib

        return getattr(importlib.import_module(self.module), self.name)

    def __contains__(self, value):
        return value in self._values()

    def __iter__(self):
        return iter(()) if _Choices.building else iter(self._values())


def _given(**options):
    """The options given on the command line; the others take the library's defaults."""
    return {k: v for k, v in options.items() if v is not None}


def _plan(files, folders=None):
    """The command's outputs, checked before any work (lsadphoto._atomic)."""
    from ._atomic import plan_outputs

    return plan_outputs(files, folders=folders)


def _load_profile(path):
    from .calibrate.profile import load_profile

    return load_profile(path) if path else None


def cmd_luminance(args):
    from .calibrate.spot import SpotReading
    from .io import write_exr, write_false_colour_png, write_hdr
    from .luminance import luminance_from_raw
    from .raw.decode import read_dark_frame

    if Path(args.output).suffix.lower() != ".exr":
        raise BadInputError(f"output {args.output} must end in .exr")
    plan = _plan({"exr": args.output, "hdr": args.hdr, "png": args.png})
    outputs = plan.files
    angle = {} if args.acceptance_angle_deg is None else {"acceptance_angle": np.deg2rad(args.acceptance_angle_deg)}
    spots = [SpotReading.parse(s, **angle) for s in args.spot or []]
    dark = read_dark_frame(args.dark_frame) if args.dark_frame else None
    illuminance = None
    if args.illuminance is not None:
        from .calibrate.illuminance import IlluminanceReading

        illuminance = IlluminanceReading(args.illuminance, **(
            {} if args.illuminance_uncertainty is None else {"relative_uncertainty": args.illuminance_uncertainty}))
    result = luminance_from_raw(
        args.raw, spots=spots, profile=_load_profile(args.profile), dark_frame=dark,
        illuminance=illuminance, nd_filter=args.nd_filter,
        **_given(demosaic=args.demosaic, colour_method=args.colour_method),
    )
    writers = {"exr": write_exr, "hdr": write_hdr, "png": write_false_colour_png}
    with plan.write() as temps:
        for kind, temp in temps.items():
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
        if summary["nominal"]:
            print(f"  camera profile {summary['profile']!r}: nominal (not measured) "
                  f"{', '.join(summary['nominal'])}; see --json camera_values")
    return 0


def cmd_calibrate_profile(args):
    from .calibrate.consistency import check_profile_frames
    from .calibrate.draft import draft_profile
    from .calibrate.profile import save_profile

    plan = _plan({"profile": args.output})
    profile = draft_profile(args.raw[0])
    if args.id:
        profile.id = args.id
    check_profile_frames(profile, args.raw[1:])
    with plan.write() as temps:
        save_profile(profile, temps["profile"])
    record = {"output": args.output, "id": profile.id, "sources": profile.sources,
              "nominal": profile.nominal_values(), "notes": profile.notes, "frames": [str(p) for p in args.raw]}
    if args.json:
        _print_json(record)
    else:
        print(f"wrote {args.output}: {profile.camera or 'unknown camera'}, {profile.lens or 'unknown lens'}")
        for key, source in profile.sources.items():
            print(f"  {key}: {source}")
        for note in profile.notes:
            print(f"  note: {note}")
        if record["nominal"]:
            print(f"  nominal, to calibrate: {', '.join(record['nominal'])}")
    return 0


def _rotation_vignetting(args):
    """The rotation method: (model, record) from --rotation frames and --target."""
    from .calibrate.vignetting import fit_vignetting_rotation
    from .raw.decode import decode_raw

    if not args.target:
        raise BadInputError("--rotation needs --target ROW,COL (the target in the first frame, sensor px)")
    try:
        target = tuple(float(v) for v in args.target.split(","))
    except ValueError:
        target = ()
    if len(target) != 2:
        raise BadInputError(f"--target must be ROW,COL, got {args.target!r}")
    frames = [decode_raw(p, **_given(demosaic=args.demosaic)) for p in args.rotation]
    f_numbers = {f.metadata.f_number for f in frames}
    if len(f_numbers) > 1:
        raise BadInputError(f"rotation frames mix apertures {sorted(f_numbers)}: fit one aperture at a time")
    model, samples = fit_vignetting_rotation(
        [f.rgb.sum(axis=-1) for f in frames], target, frames[0].sensor_shape, binning=frames[0].binning,
        **_given(degree=args.degree), saturated=[f.saturated.any(axis=-1) for f in frames], f_number=f_numbers.pop())
    model.focal_length = frames[0].metadata.focal_length
    return model, {"method": "rotation", "samples": samples, "frames": [str(p) for p in args.rotation]}


def cmd_calibrate_vignetting(args):
    from .calibrate.vignetting import fit_vignetting_polynomial
    from .raw.decode import decode_raw

    if bool(args.flat) == bool(args.rotation):
        raise BadInputError("give flat-field frames or --rotation frames (one of them)")
    plan = _plan({"profile": args.output})
    if args.rotation:
        model, record = _rotation_vignetting(args)
        return _save_vignetting(args, plan, model, record)
    frames = [decode_raw(p, **_given(demosaic=args.demosaic)) for p in args.flat]
    shape = frames[0].sensor_shape
    for f in frames[1:]:
        if f.sensor_shape != shape:
            raise BadInputError(f"flat-field frames differ in size: {f.path} is {f.sensor_shape}, not {shape}")
    rgb = np.mean([f.rgb for f in frames], axis=0)
    saturated = np.any([f.saturated.any(axis=-1) for f in frames], axis=0)
    model = fit_vignetting_polynomial(rgb.sum(axis=-1), shape, binning=frames[0].binning,
                                      saturated=saturated, **_given(degree=args.degree))
    model.f_number, model.focal_length = frames[0].metadata.f_number, frames[0].metadata.focal_length
    return _save_vignetting(args, plan, model, {"method": "flat-field", "frames": [str(p) for p in args.flat]})


def _save_vignetting(args, plan, model, record):
    from ._provenance import timestamp
    from .calibrate.profile import CameraProfile, save_profile

    profile = _load_profile(args.profile) or CameraProfile(id=args.id or "vignetting-fit")
    profile.vignetting = model
    profile.provenance = dict(profile.provenance, vignetting_fit=f"lsadphoto {__version__}, {timestamp()}, "
                              f"{record['method']}: from " + ", ".join(Path(p).name for p in record["frames"]))
    profile.sources = dict(profile.sources, vignetting=f"{record['method']} fit, {len(record['frames'])} frames")
    profile.nominal = [n for n in profile.nominal if n != "vignetting"]
    with plan.write() as temps:
        save_profile(profile, temps["profile"])
    record = dict(record, output=args.output, coefficients=model.coefficients, rms_residual=model.rms_residual,
                  uncertainty=model.uncertainty, f_number=model.f_number)
    if args.json:
        _print_json(record)
    else:
        coeffs = ", ".join(f"{c:.5g}" for c in model.coefficients)
        extra = "" if model.uncertainty is None else f", uncertainty ≤ {100 * model.uncertainty:.2f} %"
        print(f"wrote {args.output}: V = 1 + Σ a_k r^2k with a = [{coeffs}] ({record['method']}), RMS residual "
              f"{100 * model.rms_residual:.2f} %{extra}")
    return 0


def cmd_calibrate_noise(args):
    from .calibrate.noise import fit_photon_transfer
    from .calibrate.profile import CameraProfile, save_profile
    from .raw.bracket import NoiseModel
    from .raw.decode import decode_raw

    if len(args.flat) % 2 or len(args.flat) < 6:
        raise BadInputError(f"give flat frames in pairs (two per exposure level, at least three levels), "
                            f"got {len(args.flat)}")
    if args.dark and len(args.dark) != 2:
        raise BadInputError(f"--dark takes two dark frames, got {len(args.dark)}")
    plan = _plan({"profile": args.output})
    frames = [decode_raw(p) for p in args.flat]
    isos = {f.metadata.iso for f in frames}
    if len(isos) != 1 or None in isos:
        raise BadInputError(f"flat frames must share one recorded ISO, got {sorted(map(str, isos))}")
    pairs = []
    for a, b in zip(frames[0::2], frames[1::2]):
        if a.metadata.exposure_time != b.metadata.exposure_time:
            raise BadInputError(f"{a.path} and {b.path} form a pair but differ in exposure time "
                                f"({a.metadata.exposure_time} s, {b.metadata.exposure_time} s)")
        pairs.append((a.rgb[..., [0, 2]], b.rgb[..., [0, 2]]))
    dark = None
    if args.dark:
        d = [decode_raw(p) for p in args.dark]
        dark = (d[0].rgb[..., [0, 2]], d[1].rgb[..., [0, 2]])
    fit = fit_photon_transfer(pairs, iso=isos.pop(), dark_pair=dark)
    profile = _load_profile(args.profile) or CameraProfile(id=args.id or "noise-fit")
    profile.noise = NoiseModel(full_well=fit.full_well, read_noise=fit.read_noise)
    profile.noise_measured = True
    profile.sources = dict(profile.sources, noise=(
        f"photon transfer, {len(pairs)} pairs at ISO {fit.iso:g}, read noise from the {fit.read_noise_source}"))
    profile.nominal = [n for n in profile.nominal if n != "noise"]
    with plan.write() as temps:
        save_profile(profile, temps["profile"])
    record = {"output": args.output, "full_well_electrons": fit.full_well, "read_noise_electrons": fit.read_noise,
              "gain_electrons": fit.gain, "iso": fit.iso, "rms_residual": fit.rms_residual,
              "read_noise_source": fit.read_noise_source, "points": fit.points}
    if args.json:
        _print_json(record)
    else:
        print(f"wrote {args.output}: full well {fit.full_well:.4g} e⁻ at ISO 100, read noise {fit.read_noise:.3g} e⁻ "
              f"({fit.read_noise_source}); RMS residual {100 * fit.rms_residual:.1f} %")
    return 0


def cmd_calibrate_geometry(args):
    from .calibrate.geometric import calibrate_geometry, parse_pattern
    from ._provenance import timestamp
    from .calibrate.profile import CameraProfile, save_profile

    plan = _plan({"profile": args.output})
    result = calibrate_geometry(args.images, pattern=parse_pattern(args.pattern), **_given(model=args.model))
    profile = _load_profile(args.profile) or CameraProfile(id=args.id or "geometry-fit")
    profile.lens_projection = result.projection
    profile.width, profile.height = result.width, result.height
    profile.provenance = dict(profile.provenance, geometry_fit=(
        f"lsadphoto {__version__}, {timestamp()}: {result.model} model, pattern {result.pattern}, RMS {result.rms_px:.3f} px, "
        f"{len(result.summary()['used_images'])} views"))
    with plan.write() as temps:
        save_profile(profile, temps["profile"])
    summary = dict(result.summary(), output=args.output)
    if args.json:
        _print_json(summary)
    else:
        print(f"wrote {args.output}: {result.model} model, RMS {result.rms_px:.3f} px, "
              f"{len(summary['used_images'])} views used, {len(summary['rejected_images'])} rejected")
        for item in summary["rejected_images"]:
            print(f"  rejected {item['name']}: {item['reason']}")
    return 0


def _vector(text, name):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3:
        raise BadInputError(f"{name} must be three numbers X,Y,Z, got {text!r}")
    return values


def _line_of_sight(text, lmap):
    """``X,Y,Z`` (camera frame) or ``px:ROW,COL`` (through an image point)."""
    if text is None:
        return None
    if text.startswith("px:"):
        try:
            row, col = (float(v) for v in text[3:].split(","))
        except ValueError:
            raise BadInputError(f"--line-of-sight px:ROW,COL needs two numbers, got {text!r}") from None
        rows, cols = lmap.shape
        if not (-0.5 <= row <= rows - 0.5 and -0.5 <= col <= cols - 0.5):
            raise BadInputError(f"--line-of-sight {text}: the point is off the image ({rows}×{cols} px: "
                                f"ROW 0…{rows - 1}, COL 0…{cols - 1})")
        direction = lmap.projection.directions(row, col)
        if not np.all(np.isfinite(direction)):
            raise BadInputError(f"--line-of-sight {text}: the point is outside the image's valid area")
        return list(direction)
    return _vector(text, "--line-of-sight")


def _numbers(text, name, counts):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in counts:
        raise BadInputError(f"{name} needs {' or '.join(map(str, counts))} comma-separated "
                            f"numbers, got {text!r}")
    return values


def _centre_and_angles(text, name):
    """``px:ROW,COL,DEG1[,DEG2]`` or ``X,Y,Z,DEG1[,DEG2]``: (centre, angles [deg])."""
    if text.startswith("px:"):
        values = _numbers(text[3:], name, (3, 4))
        return values[:2], values[2:]
    values = _numbers(text, name, (4, 5))
    return values[:3], values[3:]


def _task(text):
    """``--task``: ``px:ROW,COL`` (image point) or ``X,Y,Z`` (direction)."""
    if text is None:
        return None
    if text.startswith("px:"):
        return _numbers(text[3:], "--task px:ROW,COL", (2,))
    return _vector(text, "--task")


def _band_and_zones(args):
    """score_map keywords of --band-deg and --zones (score and view take them alike)."""
    options = {}
    if args.band_deg is not None:
        options["band_deg"] = args.band_deg
    if args.zones:
        options["zone_centre"], options["zone_opening_deg"] = _centre_and_angles(args.zones, "--zones")
    return options


def _evalglare_options(args):
    """score_map keywords of the evalglare 3.06 options of ``score`` (see its --help)."""
    from .io import read_map

    options = _band_and_zones(args)
    if args.mask:
        options["mask"] = read_map(args.mask)
    if args.checkfile:
        options["checkfile"] = args.checkfile
    if args.smooth:
        options["smooth"] = True
    if args.patch_deg is not None:
        options["patch_deg"] = args.patch_deg
    if args.age is not None:
        options["age"] = args.age
    if args.illuminance is not None:
        options["illuminance"] = args.illuminance
    if args.illuminance_fill:
        lux, row_max, row_min = _numbers(args.illuminance_fill, "--illuminance-fill", (3,))
        options["illuminance_fill"] = (lux, row_max, row_min)
    if args.correction_mode is not None:
        from .metrics.corrections import low_light_correction_on

        options["low_light_correction"] = low_light_correction_on(args.correction_mode)
    if args.dgp_coefficients:
        named = args.dgp_coefficients in ("evalglare", "Wienold2006")
        options["dgp_coefficients"] = args.dgp_coefficients if named else _numbers(
            args.dgp_coefficients, "--dgp-coefficients", (8,))
    return options


def _format(value, digits=3):
    return "—" if value is None else f"{value:.{digits}f}"


def _percent(fraction):
    """A relative error as a percentage to 2 significant digits ("—" where undefined)."""
    if fraction is None or not math.isfinite(fraction):
        return "—"
    return f"{100 * fraction:.2g} %"


def cmd_score(args):
    from .io import read_map
    from .metrics.grouping import DEFAULT_SEARCH_ANGLE
    from .metrics.score import score_map

    plan = _plan({"sources": args.sources_png, "contrast": args.contrast_png, "json": args.output_json})
    lmap = read_map(args.map)
    if lmap.projection is None:
        view = (lmap.provenance or {}).get("radiance_view")
        if view:
            from .io.hdr import parse_view, projection_from_view

            try:
                projection_from_view(parse_view(view), lmap.shape[1], lmap.shape[0])
            except BadInputError as exc:
                raise BadInputError(f"{args.map}: VIEW= line {view.strip()!r}: {exc}") from None
        raise BadInputError(f"{args.map} has no camera geometry (no VIEW= line or lsadphoto metadata)")
    method = args.source_method
    score = score_map(
        lmap, line_of_sight=_line_of_sight(args.line_of_sight, lmap),
        up=_vector(args.up, "--up") if args.up else None, source_method=method,
        source_threshold=args.threshold,
        task_direction=_task(args.task),
        task_opening_deg=args.task_opening_deg,
        search_angle=DEFAULT_SEARCH_ANGLE if args.search_angle_deg is None else math.radians(args.search_angle_deg),
        peak_luminance=None if args.no_peak_extraction else args.peak_luminance,
        background_method=args.background, position_index_method=args.position_index,
        source_position=args.source_position, guth_field=args.guth_field,
        noise_samples=args.noise_samples, q_noise_samples=args.q_noise_samples, n_thresholds=args.N, size_arcmin=args.alpha_arcmin,
        q_weight_exponent=args.q_weight_exponent,
        sweep=range(1, 101) if args.sweep else None, **_evalglare_options(args),
    )
    record = score.to_dict()
    record["provenance"]["input"] = str(args.map)
    with plan.write() as temps:
        if "sources" in temps:
            from .report import write_glare_source_png

            write_glare_source_png(lmap.luminance, score.source_labels, temps["sources"])
        if "contrast" in temps:
            from .report import write_contrast_png

            write_contrast_png(score.contrast, temps["contrast"])
        if "json" in temps:
            temps["json"].write_text(_json_text(record), encoding="utf-8")
    if args.json:
        _print_json(record)
    else:
        from .metrics.registry import METRICS

        u = record["uncertainty"]

        def shown(key):
            text = _with_uncertainty(record[key], u.get(key), METRICS[key].digits)
            return f"{text} {METRICS[key].unit}" if METRICS[key].unit not in ("", "–") else text

        print(f"{args.map}: {record['n_sources']:.0f} glare sources; "
              f"UGR pixel {shown('ugr_pixel')}, grouped {shown('ugr_grouped')}; "
              f"Q {shown('q')}; DGP {shown('dgp')}; E_v {shown('vertical_illuminance')}; "
              f"L_b {shown('background_luminance')}")
        biased = [f"{METRICS[key].label} {b:+.2g} (±{record['noise_bias_standard_error'][key]:.1g})"
                  for key, b in record["noise_bias"].items()
                  if b is not None and _bias_matters(b, record, key)]
        if biased:
            print("  bias from pixel noise: " + ", ".join(biased))
        for note in record["notes"]:
            print(f"  note: {note}")
    return 0


def _with_uncertainty(value, u, digits):
    """``value ± u`` with u to two significant digits and the value to the same decimal;
    ``digits`` decimals when there is no uncertainty."""
    if value is None:
        return "—"
    if not u:
        return f"{value:.{digits}f}"
    decimals = max(0, 1 - int(np.floor(np.log10(abs(u)))))
    return f"{value:.{decimals}f} ± {u:.{decimals}f}"


def _bias_matters(bias, record, key):
    """A noise bias worth printing: beyond twice its Monte Carlo error and a tenth of the
    metric's standard uncertainty."""
    error = record["noise_bias_standard_error"].get(key) or 0.0
    u = record["uncertainty"].get(key) or 0.0
    return abs(bias) > 2 * error and abs(bias) > 0.1 * u


def cmd_design(args):
    from ._progress import progress_callback
    from .design.run import run_design
    from .report.design import design_report_html

    callback, close = progress_callback("design", enabled=False if args.quiet else None)
    try:
        record = run_design(args.problem, args.output, report=design_report_html,
                            progress=None if callback is None else (lambda _stage, f: callback(f, None)),
                            log=(lambda line: None) if args.quiet or args.json else
                            (lambda line: print(line, file=sys.stderr)))
    finally:
        close()
    if args.json:
        _print_json(record)
    else:
        best = record["best"]
        if best is None:
            print(f"no design meets the constraints; wrote {args.output}/design.json with the "
                  f"{len(record['closest'])} closest designs")
        else:
            parts = [_format(v["ugr_grouped"], 3) if v["ugr_grouped"] is not None else "—"
                     for v in best["views"].values()]
            print(f"best design: {best['luminaires']} luminaires, {best['power_w']:g} W, grouped UGR "
                  f"{', '.join(parts)} ({', '.join(best['views'])}); {len(record['pareto'])} Pareto "
                  f"designs; wrote {args.output}/design.json, best.toml, report.html")
    return 0


def cmd_compare(args):
    from .compare import compare_maps
    from .io import read_map
    from .report import write_comparison_report, write_ratio_png

    plan = _plan({"ratio": args.ratio_png, "report": args.report, "json": args.output_json})
    photo, model = read_map(args.photo), read_map(args.model)
    result = compare_maps(photo, model,
                          line_of_sight=_line_of_sight(args.line_of_sight, photo) if photo.projection else None)
    record = result.to_dict()
    record["inputs"] = {"photo": str(args.photo), "model": str(args.model)}
    if args.report:
        record["report"] = str(args.report)
    with plan.write() as temps:
        if "ratio" in temps:
            write_ratio_png(result.ratio, temps["ratio"])
        if "report" in temps:
            write_comparison_report(result, temps["report"], photo=photo, model=model)
        if "json" in temps:
            temps["json"].write_text(_json_text(record), encoding="utf-8")
    if args.json:
        _print_json(record)
    else:
        f = record["field"]
        print(f"model/photo over the field: median {_format(f['median_ratio'])}, 5–95 % "
              f"{_format(f['p05_ratio'])}–{_format(f['p95_ratio'])}, RMS relative error "
              f"{_format(f['rms_relative_error'])}, within ±10 %: {_format(f['within_10_percent'])}")
        for key, m in record["metrics"].items():
            print(f"  {key}: photo {_format(m['photo'])}, model {_format(m['model'])}, "
                  f"difference {_format(m['difference'])} ± {_format(m['combined_uncertainty'])}")
    return 0


def cmd_view(args):
    from .io import read_map
    from .metrics.score import score_map
    from .viewer import check_same_geometry, write_viewer

    output = Path(args.output)
    if output.suffix.lower() not in (".html", ".htm"):
        raise BadInputError(f"output {args.output} must end in .html")
    plan = _plan({"html": output})
    first = read_map(args.map)
    second = read_map(args.map2) if args.map2 else None
    if second is not None:
        check_same_geometry(first, second, names=(str(args.map), str(args.map2)))
    options = _band_and_zones(args)
    scores = [None, None]
    if not args.no_score:
        scores = [score_map(m, **options) if m is not None and m.projection is not None
                  else None for m in (first, second)]
    names = (args.name or Path(args.map).stem,
             args.name2 or (Path(args.map2).stem if args.map2 else "second"))
    with plan.write() as temps:
        write_viewer(first, temps["html"], second=second, score=scores[0], second_score=scores[1],
                     names=names, title=args.title)
    record = {"output": str(output), "bytes": output.stat().st_size,
              "maps": [str(args.map)] + ([str(args.map2)] if args.map2 else []),
              "scored": [s is not None for s in scores[:1 + (second is not None)]]}
    if args.json:
        _print_json(record)
    else:
        print(f"wrote {output} ({record['bytes'] / 1e6:.1f} MB)")
    return 0


def cmd_study(args):
    from .study import run_study

    if args.report:  # before any work: a typo must not become a report of an empty survey
        from .report import check_survey_folder

        check_survey_folder(args.report, option="--report")
    report = Path(args.report) / "report.html" if args.report else None
    plan = _plan({"report": report, "json": args.output_json}, folders={"figures": args.figures})
    result = run_study(args.ratings, args.metrics, metric=args.metric,
                       sweep_prefix=args.sweep_prefix or None, jitter=args.jitter,
                       n_jitter=args.n_jitter, n_bootstrap=args.n_bootstrap,
                       confidence=args.confidence, seed=args.seed, **_given(direction=args.direction))
    record = result.to_dict()
    with plan.write() as temps:
        if "figures" in temps:
            record["figures"] = [str(Path(args.figures) / p.name) for p in result.figures(temps["figures"])]
        if "report" in temps:
            from .report import write_survey_report

            write_survey_report(args.report, temps["report"], study=result)
            record["report"] = str(report)
        if "json" in temps:
            temps["json"].write_text(_json_text(record), encoding="utf-8")
    if args.json:
        _print_json(record)
        return 0
    c = record["correlations"][args.metric]
    ci = c["pearson_ci"] or [None, None]
    print(f"{args.metric} vs mean rating over {c['n']} scenes: Pearson r = {_format(c['pearson_r'])} "
          f"[{_format(ci[0])}, {_format(ci[1])}] ({c['chaddock'] or 'undefined'}), Spearman ρ = "
          f"{_format(c['spearman_rho'])}, Kendall τ = {_format(c['kendall_tau'])}")
    sweep = record.get("sweep")
    if sweep and sweep.get("best"):
        best = sweep["best"]
        print(f"best N = {best['n']:g}: r = {_format(best['r'])}")
    loo = record.get("leave_one_out")
    if loo:
        print(f"leave-one-scene-out choice of N: out-of-sample r = {_format(loo['r_loo'])} "
              f"(in-sample {_format(loo['r_in_sample'])})")
    jit = record.get("jitter")
    if jit:
        change = jit["max_relative_change"]
        print(f"ratings jittered ±{jit['half_width']:g} × {jit['n_trials']}: r = {_format(jit['mean'])} ± "
              f"{_format(jit['sd'])}, largest relative change "
              f"{'—' if change is None else f'{100 * change:.1f} %'}")
    for note in record.get("notes", []):
        print(f"  note: {note}")
    if "report" in record:
        print(f"report: {record['report']}")
    return 0


def cmd_survey(args):
    from .survey import check_score_options, run_survey

    score_options = {}
    if args.N is not None:
        score_options["n_thresholds"] = args.N
    if args.alpha_arcmin is not None:
        score_options["size_arcmin"] = args.alpha_arcmin
    # Checked here to name the options as the user gave them; run_survey checks them again.
    score_options = check_score_options(score_options, source="--N/--alpha-arcmin")
    result = run_survey(args.manifest, args.output, workers=args.workers, dask_address=args.dask,
                        progress=not args.quiet, score_options=score_options or None)
    report = None
    if not args.no_report:
        from .report import write_survey_report

        report = write_survey_report(args.output)
    if args.json:
        _print_json(result.to_dict())
    else:
        print(f"{args.output}: {len(result.table)} views finished ({len(result.processed)} processed now, "
              f"{len(result.skipped)} already done), {len(result.failures)} failed; "
              f"table {Path(args.output) / 'metrics.csv'}")
        for view, reason in result.failures:
            print(f"  failed {view}: {reason}")
        if report is not None:
            print(f"report: {report}")
    return 1 if result.failures else 0


def _load_any_scene(path):
    """Our TOML scene, a Radiance scene (.rad) or rad file (.rif): :func:`lsadphoto.solver.read_scene`."""
    from .solver import read_scene

    return read_scene(path)


def cmd_simulate(args):
    from ._progress import progress_callback
    from .solver import simulate

    plan = _plan({"store": args.output})
    if args.samples is None and args.target_error is None:
        args.samples = 65536
    scene = _load_any_scene(args.scene)
    callback, close = progress_callback("simulating", enabled=False if args.quiet else None)
    try:
        store = simulate(scene, samples=args.samples, target_error=args.target_error, seed=args.seed,
                         progress=callback, **_given(near_field=args.near_field, fresnel_rule=args.fresnel_rule))
    finally:
        close()
    if args.surface_cache:
        store.surface_cache = _build_cache(store, args)
    with plan.write() as temps:
        store.save(temps["store"])
    record = {"output": str(args.output), "scene": str(args.scene), "chains": store.chains,
              "nodes": store.nodes, "provenance": store.provenance}
    if args.json:
        _print_json(record)
    else:
        achieved = store.provenance.get("achieved_relative_error")
        extra = ("" if achieved is None else
                 f"; relative error of the {store.provenance['error_measured_on']} {achieved:.2%}")
        print(f"wrote {args.output}: {store.chains} light chains, {store.nodes} nodes{extra}")
    return 0


def _add_fresnel_rule(parser, default):
    parser.add_argument("--fresnel-rule", choices=_Choices("lsadphoto.solver.materials", "FRESNEL_RULES"),
                        help="smooth plastic, metal and trans: 'reciprocal' weights all light on their diffuse "
                             "part by 1 − F(μ_i) (a reciprocal BRDF); 'radiance' only the light straight from "
                             "Radiance's light sources (light, spotlight, glow of radius > 0, the sun), as Radiance "
                             f"renders the same file {default}")


def _build_cache(store, args):
    from ._progress import progress_callback
    from .solver.integrators.surface_cache import build_surface_cache

    callback, close = progress_callback("surface cache", enabled=False if args.quiet else None)
    try:
        return build_surface_cache(store, spacing=args.cache_spacing,
                                   **({} if args.cache_nodes is None else {"nodes": args.cache_nodes}),
                                   seed=args.seed, workers=os.cpu_count() or 1, progress=callback)
    finally:
        close()


def _render_pose(args, scene):
    """Projection, eye position and camera-to-world rotation from the render options."""
    from .io.hdr import parse_view, projection_from_view
    from .solver import camera_to_world

    if args.view:
        if not args.size:
            raise BadInputError("--view needs --size WxH")
        width, height = _size(args.size)
        from .solver.formats.views import view_options

        view = parse_view(view_options(args.view), strict=True)  # -vf files expanded
        if "vp" not in view:
            raise BadInputError(f"--view {args.view!r} gives no eye position (-vp X Y Z [m])")
        projection = projection_from_view(view, width, height)
        position = view.get("vp", [0.0, 0.0, 0.0])
        rotation = camera_to_world(view.get("vd", [0.0, 1.0, 0.0]), view.get("vu", [0.0, 0.0, 1.0]))
        return projection, position, rotation
    if args.profile:
        profile = _load_profile(args.profile)
        if not (profile.width and profile.height):
            raise BadInputError(f"profile {args.profile} gives no image size (sensor.width_px, sensor.height_px)")
        # The calibrated lens model, or the nominal pinhole of [lens_model] focal_length_mm.
        projection = profile.projection((profile.height, profile.width))
        if args.size:
            width, height = _size(args.size)
            factor = projection.width // width
            if factor < 1 or projection.width != factor * width or projection.height // factor != height:
                raise BadInputError(f"--size {args.size} is not the profile's {projection.width}×"
                                    f"{projection.height} binned by a whole factor")
            projection = projection.binned(factor)
        if args.position is None or args.line_of_sight is None:
            raise BadInputError("--profile needs --position X,Y,Z and --line-of-sight X,Y,Z (world)")
        up = _vector(args.up, "--up") if args.up else [0.0, 0.0, 1.0]
        return (projection, _vector(args.position, "--position"),
                camera_to_world(_vector(args.line_of_sight, "--line-of-sight"), up))
    views = scene.views
    if not views:
        raise BadInputError("give --view, --profile or a scene with [[views]] (then --view-name)")
    if args.view_name:
        chosen = [v for v in views if v.name == args.view_name]
        if not chosen:
            raise BadInputError(f"no view {args.view_name!r}; views: {', '.join(v.name for v in views)}")
        v = chosen[0]
    else:
        v = views[0]
    return v.projection, v.position, v.rotation


def _size(text):
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise BadInputError(f"--size must be WIDTHxHEIGHT, got {text!r}") from None
    if width < 1 or height < 1:
        raise BadInputError(f"--size must be positive, got {text!r}")
    return width, height


def cmd_render(args):
    from ._progress import progress_callback
    from .io import write_exr, write_hdr
    from .solver import load_store, render
    from .solver.rendering import DEFAULT_TARGET_ERROR, choose_estimator

    if Path(args.output).suffix.lower() != ".exr":
        raise BadInputError(f"output {args.output} must end in .exr")
    plan = _plan({"exr": args.output, "hdr": args.hdr})
    outputs = plan.files
    source = Path(args.source)
    cache_options = [o for o, v in (("--cache-spacing", args.cache_spacing),
                                    ("--cache-nodes", args.cache_nodes)) if v is not None]
    if source.suffix.lower() == ".npz":
        store_or_scene = load_store(source)
        scene = store_or_scene.scene
        for option, value in (("--samples", args.samples), ("--target-error", args.target_error)):
            if value is not None:
                raise BadInputError(f"{option} applies when rendering a scene directly; the store "
                                    f"{source} holds {store_or_scene.chains} chains (simulate again for more)")
        if cache_options and store_or_scene.surface_cache is not None:
            raise BadInputError(f"{', '.join(cache_options)} cannot apply: the store {source} already holds "
                                f"a surface cache (spacing {store_or_scene.surface_cache.spacing:.3g} m); "
                                "build another with simulate --surface-cache")
        target = None
    else:
        store_or_scene = scene = _load_any_scene(source)
        target = args.target_error
        if target is None and args.samples is None:
            target = DEFAULT_TARGET_ERROR
    estimator = args.estimator
    if estimator == "auto":
        estimator = choose_estimator(store_or_scene, samples=args.samples, target_error=target)[0]
    if cache_options and estimator != "cache":
        raise BadInputError(f"{', '.join(cache_options)} apply to the surface cache (--estimator cache)")
    projection, position, rotation = _render_pose(args, scene)
    nodes = args.nodes_per_pixel
    if nodes not in ("auto", "all"):
        if estimator == "cache":
            raise BadInputError("--nodes-per-pixel applies to --estimator local")
        try:
            nodes = int(nodes)
        except ValueError:
            raise BadInputError(f"--nodes-per-pixel must be a positive integer, 'all' or 'auto', got {nodes!r}") from None
    options = ({"cache_spacing": args.cache_spacing, "cache_nodes": args.cache_nodes}
               if estimator == "cache" else {"nodes_per_pixel": None if nodes == "all" else nodes})
    callback, close = progress_callback("rendering", enabled=False if args.quiet else None)
    try:
        lmap = render(store_or_scene, projection, position=position, rotation=rotation, estimator=args.estimator,
                      samples=args.samples, target_error=target, seed=args.seed, workers=os.cpu_count() or 1,
                      progress=callback, **options, **_given(fresnel_rule=args.fresnel_rule))
    finally:
        close()
    writers = {"exr": write_exr, "hdr": write_hdr}
    with plan.write() as temps:
        for kind, temp in temps.items():
            writers[kind](lmap, temp)
    record = {"outputs": {k: str(v) for k, v in outputs.items()}, "provenance": lmap.provenance}
    if args.json:
        _print_json(record)
    else:
        p = lmap.provenance
        print(f"wrote {args.output}: {projection.width}×{projection.height} px, field-mean luminance "
              f"{_format(p.get('field_mean_luminance'), 4)} cd/m² (relative Monte Carlo error "
              f"{_percent(p.get('achieved_relative_error'))}); per-pixel relative error: median "
              f"{_percent(p.get('pixel_relative_error_median'))}, 95th percentile "
              f"{_percent(p.get('pixel_relative_error_p95'))}, mean absolute (expected) "
              f"{_percent(p.get('pixel_relative_error_expected_mean_absolute'))}"
              f"{' — biased (clamped near field)' if p.get('near_field') == 'clamp' else ''}"
              + (f"; in quadrature of noise {_percent(p['pixel_relative_noise_median'])} / "
                 f"{_percent(p['pixel_relative_noise_p95'])} and estimated interpolation bias "
                 f"{_percent(p['pixel_relative_bias_median'])} / {_percent(p['pixel_relative_bias_p95'])}"
                 " (median / 95th percentile)" if "pixel_relative_bias_median" in p else ""))
        if p.get("estimator_choice"):
            print(f"estimator {p['estimator_choice']}")
        if p.get("target_error") is not None:
            chains = " → ".join(str(r["chains"]) for r in p["rounds"])
            print(f"target per-pixel error {_percent(p['target_error'])} "
                  f"{'reached' if p['target_reached'] else 'NOT reached'} (chains per round: {chains})")
    return 0


def _add_cache_options(sub):
    sub.add_argument("--cache-spacing", type=float, metavar="M",
                     help="surface-cache point spacing [m] (default 1/24 of the scene's diagonal)")
    sub.add_argument("--cache-nodes", type=int, metavar="N",
                     help="node draws per surface-cache point (default 8192)")


class _Parser(argparse.ArgumentParser):
    """argparse, with a hint where a value that starts with '-' was taken for an option."""

    #: The arguments being parsed (set by :func:`main`), to quote the value in the hint.
    argv = ()

    def error(self, message):
        if message.startswith("argument ") and "expected one argument" in message:
            option = message.split()[1].rstrip(":").split("/")[-1]
            argv = list(_Parser.argv)
            value = next((argv[i + 1] for i, a in enumerate(argv[:-1]) if a == option), "-VALUE")
            message += f" (a value that starts with '-' must be attached with '=': {option}={value})"
        super().error(message)


def build_parser():
    _Choices.building = True
    try:
        return _build_parser()
    finally:
        _Choices.building = False


def _build_parser():
    from .constants import LS100_ACCEPTANCE_ANGLE

    demosaic = _Choices("lsadphoto.raw.methods", "DEMOSAIC_METHODS")
    parser = _Parser(prog=PROG, description="Calibrated luminance maps from RAW photographs.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of errors")
    sub = parser.add_subparsers(dest="command", required=True)

    lum = sub.add_parser("luminance", help="RAW file(s) of one view → absolute luminance map")
    lum.add_argument("raw", nargs="+", help="RAW file, or several forming an exposure bracket")
    lum.add_argument("--spot", action="append", metavar="ROW,COL,CD_M2",
                     help="spot-meter reading at a full-resolution pixel (repeatable)")
    lum.add_argument("--acceptance-angle-deg", type=float,
                     help=f"spot meter acceptance angle, full cone [deg] (default: LS-100, "
                          f"{np.rad2deg(LS100_ACCEPTANCE_ANGLE):g})")
    lum.add_argument("--profile", help="camera profile (TOML); default: drafted from the file (EXIF, lensfun)")
    lum.add_argument("--illuminance", type=float, metavar="LUX",
                     help="illuminance at the lens, meter facing along the optical axis (hemispherical maps): "
                          "calibrates the map, or cross-checks the spots")
    lum.add_argument("--illuminance-uncertainty", type=float, metavar="REL",
                     help="relative standard uncertainty of the illuminance meter (default 0.043: DIN 5032-7 class B)")
    lum.add_argument("--nd-filter", type=float, nargs="+", metavar="STOPS",
                     help="neutral-density filter of each frame in stops, in the order of the RAW files (0 for none)")
    lum.add_argument("--demosaic", choices=demosaic, help="demosaicing (default: the first)")
    lum.add_argument("--colour-method", choices=_Choices("lsadphoto.raw.colour", "COLOUR_METHODS"),
                     help="camera RGB → XYZ source (default: the first)")
    lum.add_argument("--dark-frame", action="append", metavar="RAW", help="dark frame(s) for a black-level map")
    lum.add_argument("-o", "--output", required=True, help="output OpenEXR map (.exr)")
    lum.add_argument("--hdr", help="also write a Radiance HDR map")
    lum.add_argument("--png", help="also write a false-colour PNG")
    lum.add_argument("--json", action="store_true", help="print a JSON summary")
    lum.set_defaults(func=cmd_luminance)

    cal = sub.add_parser("calibrate", help="camera calibration")
    calsub = cal.add_subparsers(dest="what", required=True)
    vig = calsub.add_parser("vignetting", help="fit a vignetting polynomial from flat-field RAW frames or a "
                            "rotation sequence")
    vig.add_argument("flat", nargs="*", help="flat-field RAW frames (uniform diffuse field, same settings)")
    vig.add_argument("--rotation", nargs="+", metavar="RAW",
                     help="rotation method: RAW frames of a fixed, uniformly lit target while the camera turns "
                          "about its entrance pupil (one aperture)")
    vig.add_argument("--target", metavar="ROW,COL", help="the target's position in the first --rotation frame [sensor px]")
    vig.add_argument("-o", "--output", required=True, help="camera profile to write (TOML)")
    vig.add_argument("--profile", help="profile to start from (its other sections are kept)")
    vig.add_argument("--id", help="profile id when no --profile is given")
    vig.add_argument("--degree", type=int, help="number of even polynomial terms (default 3, at most 6)")
    vig.add_argument("--demosaic", choices=demosaic, help="demosaicing (default: the first)")
    vig.add_argument("--json", action="store_true")
    vig.set_defaults(func=cmd_calibrate_vignetting)
    noi = calsub.add_parser("noise", help="measure the noise model ([noise]) by photon transfer from pairs of "
                            "flat frames at several exposures")
    noi.add_argument("flat", nargs="+", help="flat frames in pairs: two per exposure level, three levels or more")
    noi.add_argument("--dark", nargs=2, metavar="RAW", help="two dark frames (lens cap on, same settings)")
    noi.add_argument("-o", "--output", required=True, help="camera profile to write (TOML)")
    noi.add_argument("--profile", help="profile to start from (its other sections are kept)")
    noi.add_argument("--id", help="profile id when no --profile is given")
    noi.add_argument("--json", action="store_true")
    noi.set_defaults(func=cmd_calibrate_noise)
    prof = calsub.add_parser("profile", help="draft a camera profile from RAW files (EXIF and the lensfun "
                             "database), to edit and calibrate further")
    prof.add_argument("raw", nargs="+", help="RAW file(s) of one camera, lens, focal length and aperture")
    prof.add_argument("-o", "--output", required=True, help="camera profile to write (TOML)")
    prof.add_argument("--id", help="profile id (default: 'drafted from FILE')")
    prof.add_argument("--json", action="store_true")
    prof.set_defaults(func=cmd_calibrate_profile)
    geo = calsub.add_parser("geometry", help="calibrate the camera geometry from chessboard or ChArUco images (OpenCV)")
    geo.add_argument("images", nargs="+", help="images of a chessboard or ChArUco board (8-bit, any format OpenCV reads)")
    geo.add_argument("--pattern", required=True, metavar="PATTERN",
                     help="chessboard:COLSxROWS:SQUARE_MM (inner corners, square side [mm]) or "
                          "charuco:COLSxROWS:SQUARE_MM:MARKER_MM[:DICT] (squares, square and marker "
                          "sides [mm], ArUco dictionary, default DICT_5X5_100); e.g. chessboard:9x6:25, "
                          "charuco:9x6:35:26")
    geo.add_argument("--model", choices=_Choices("lsadphoto.calibrate.geometric", "MODELS"),
                     help="camera model (default: the first)")
    geo.add_argument("-o", "--output", required=True, help="camera profile to write (TOML)")
    geo.add_argument("--profile", help="profile to start from (its other sections are kept)")
    geo.add_argument("--id", help="profile id when no --profile is given")
    geo.add_argument("--json", action="store_true")
    geo.set_defaults(func=cmd_calibrate_geometry)

    sc = sub.add_parser("score", help="score a luminance map (EXR, or Radiance HDR with VIEW=): UGR, Q, DGP, …")
    sc.add_argument("map", help="luminance map: our .exr, or a Radiance .hdr with a VIEW= line")
    sc.add_argument("--line-of-sight", metavar="X,Y,Z|px:ROW,COL",
                    help="line of sight in the camera frame (x right, y down, z forward) or through "
                         "an image point; default the map's, else the optical axis")
    sc.add_argument("--up", metavar="X,Y,Z", help="view-up vector in the camera frame (default camera up)")
    sc.add_argument("--source-method", choices=_Choices("lsadphoto.metrics.sources", "SOURCE_METHODS"), default="fixed",
                    help="glare-source rule (default: fixed threshold)")
    sc.add_argument("--threshold", type=float,
                    help="glare-source threshold [cd/m²] (fixed, default 2000) or factor (task, mean; default 5)")
    sc.add_argument("--task", metavar="px:ROW,COL|X,Y,Z",
                    help="task area centre (evalglare -t): an image point or a direction; its mean "
                         "luminance is reported (task) and used by --source-method task and PGSV "
                         "(default for the task rule: the line of sight)")
    sc.add_argument("--task-opening-deg", type=float, default=20.0,
                    help="task cone full opening angle [deg] (evalglare -t angle × 180/π)")
    sc.add_argument("--search-angle-deg", type=float, metavar="A",
                    help="grouping opening angle [deg] (evalglare -r angle × 180/π; default evalglare's "
                         "0.2 rad = 11.46°)")
    sc.add_argument("--peak-luminance", type=float, default=50000.0, help="peak-extraction limit [cd/m²]")
    sc.add_argument("--no-peak-extraction", action="store_true")
    sc.add_argument("--background", choices=_Choices("lsadphoto.metrics.field", "BACKGROUND_METHODS"),
                    default="CIE", help="background luminance definition")
    sc.add_argument("--position-index", choices=_Choices("lsadphoto.geometry.position_index", "METHODS"),
                    default="evalglare")
    sc.add_argument("--source-position", choices=_Choices("lsadphoto.metrics.grouping", "SOURCE_POSITIONS"), default="evalglare",
                    help="where a source's position index is taken: evalglare's pixel of its "
                         "L·ω-weighted mean pixel position (default, as evalglare 3.06), or its "
                         "L·ω-weighted mean direction")
    sc.add_argument("--guth-field", type=int, choices=_Choices("lsadphoto.geometry.position_index", "GUTH_FIELDS"), help="evaluate only Guth's total (1) or central (2) field")
    sc.add_argument("--N", type=float, default=50.0, help="threshold count N of the Q criterion (default 50)")
    sc.add_argument("--alpha-arcmin", type=float, default=10.0, help="critical detail α [arcmin] (default 10)")
    sc.add_argument("--q-weight-exponent", type=float, default=1,
                    help="Q weight w = P^-m, m ≥ 0 (default m = 1; FORMULAS.md §5.2 names 0, 1, 2)")
    sc.add_argument("--sweep", action="store_true", help="also compute Q(N) for N = 1…100 in one pass")
    sc.add_argument("--noise-samples", type=int, default=64,
                    help="draws of the field sums for the per-pixel noise of maps that carry a "
                         "per-pixel uncertainty (0: off; default 64)")
    sc.add_argument("--q-noise-samples", type=int, default=8,
                    help="resampled maps for Q's noise and bias (0: off; default 8)")
    eg = sc.add_argument_group("evalglare 3.06 analyses (angles in degrees, evalglare's radians × 180/π)")
    eg.add_argument("--band-deg", type=float, metavar="A",
                    help="evalglare -B: statistics of the horizontal band of half-width A about the "
                         "middle row (0 < A ≤ 180); JSON 'band'")
    eg.add_argument("--zones", metavar="px:ROW,COL,DEG1[,DEG2]|X,Y,Z,DEG1[,DEG2]",
                    help="evalglare -l (one angle) / -L (two): zone 1 a cone of full opening DEG1 "
                         "about the centre, zone 2 the ring out to DEG2; sources are split at the "
                         "zone borders; JSON 'zones', each source's 'zone'")
    eg.add_argument("--mask", metavar="FILE",
                    help="evalglare -A: statistics of the pixels of a same-size picture above "
                         "0.1 cd/m² (the window), with PGSV, PGSV_sat, PGSV_con; JSON 'mask'")
    eg.add_argument("--smooth", action="store_true",
                    help="evalglare -s: pixels around sources join them (smoothing)")
    eg.add_argument("--patch-deg", type=float, metavar="A",
                    help="evalglare -z A 1: sources are fixed patches of A degrees instead of "
                         "grouped pixels (angular fisheye only)")
    eg.add_argument("--checkfile", metavar="OUT.hdr",
                    help="evalglare -c: write a Radiance picture with the sources, band, mask and "
                         "zones in colour")
    eg.add_argument("--age", type=float, metavar="YEARS",
                    help="observer age: CIE 146 age factor 1 + (A/70)^4 of the veiling luminance "
                         "Lveil_cie (evalglare 3.06 has none)")
    eg.add_argument("--illuminance", type=float, metavar="LUX",
                    help="evalglare -i: external vertical illuminance for DGP [lx]")
    eg.add_argument("--illuminance-fill", metavar="LUX,ROW_MAX,ROW_MIN",
                    help="evalglare -I: as --illuminance, after filling cut rows with the last "
                         "known values; evalglare's y_max, y_min given as rows from the top "
                         "(row = rows - 1 - y)")
    eg.add_argument("--correction-mode", choices=_Choices("lsadphoto.metrics.corrections", "CORRECTION_MODES"),
                    help="evalglare -C: l+ DGP low-light correction on, l- or 0 off (default off)")
    eg.add_argument("--dgp-coefficients", metavar="NAME|a1,a2,a3,a4,a5,c1,c2,c3",
                    help="evalglare -w: DGP coefficients, 'evalglare' (default), 'Wienold2006' or "
                         "eight numbers")
    sc.add_argument("--sources-png", metavar="OUT.png", help="write the glare-source map")
    sc.add_argument("--contrast-png", metavar="OUT.png", help="write the Q contrast map")
    sc.add_argument("--output-json", metavar="OUT.json", help="write the JSON record to a file")
    sc.add_argument("--json", action="store_true", help="print the JSON record")
    sc.set_defaults(func=cmd_score)

    cmp_ = sub.add_parser("compare", help="compare a model map with a photo of the same view")
    cmp_.add_argument("photo", help="photo luminance map (.exr or .hdr)")
    cmp_.add_argument("model", help="model luminance map rendered through the same camera (.exr or .hdr)")
    cmp_.add_argument("--line-of-sight", metavar="X,Y,Z|px:ROW,COL", help="as for score")
    cmp_.add_argument("--ratio-png", metavar="OUT.png", help="write the per-pixel ratio map")
    cmp_.add_argument("--report", metavar="OUT.html", help="write a self-contained HTML report")
    cmp_.add_argument("--output-json", metavar="OUT.json", help="write the JSON record to a file")
    cmp_.add_argument("--json", action="store_true", help="print the JSON record")
    cmp_.set_defaults(func=cmd_compare)

    dsg = sub.add_parser("design", help="choose luminaires and their layout for a quality (Q, UGR, DGP, illuminance)")
    dsg.add_argument("problem", help="design problem (TOML, schema lsadphoto.design/1)")
    dsg.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    dsg.add_argument("--json", action="store_true", help="print the design.json record")
    dsg.add_argument("--quiet", action="store_true", help="no progress bar or stage lines")
    dsg.set_defaults(func=cmd_design)

    vw = sub.add_parser("view", help="interactive luminance viewer: one self-contained HTML file")
    vw.add_argument("map", help="luminance map (.exr or .hdr)")
    vw.add_argument("map2", nargs="?", help="a second map of the same view and camera geometry "
                    "(e.g. the model of the photo), shown side by side and as a ratio")
    vw.add_argument("-o", "--output", required=True, help="HTML file to write")
    vw.add_argument("--title", help="heading of the page (default: the first map's name)")
    vw.add_argument("--name", help="name of the first map (default: its file name)")
    vw.add_argument("--name2", help="name of the second map (default: its file name)")
    vw.add_argument("--no-score", action="store_true",
                    help="leave out the metrics overlays (glare sources, Q contrast map)")
    vw.add_argument("--band-deg", type=float, metavar="A",
                    help="also show evalglare's band (-B) of half-width A, as for score")
    vw.add_argument("--zones", metavar="px:ROW,COL,DEG1[,DEG2]|X,Y,Z,DEG1[,DEG2]",
                    help="also show evalglare's zones (-l/-L), as for score")
    vw.add_argument("--json", action="store_true", help="print a JSON summary")
    vw.set_defaults(func=cmd_view)

    st = sub.add_parser("study", help="correlate observers' ratings with metrics (the paper's analyses)")
    st.add_argument("ratings", help="RATINGS.csv: scene, observer, rating")
    st.add_argument("metrics", help="METRICS.csv: scene and metric columns (the survey's metrics.csv)")
    st.add_argument("--metric", default="q", help="metric analysed in detail (default q)")
    st.add_argument("--sweep-prefix", default="q_n", help="prefix of the Q(N) sweep columns ('' for none)")
    st.add_argument("--direction", choices=_Choices("lsadphoto.study.selection", "DIRECTIONS"),
                    help="which correlation counts as best in the N sweep (default: the first)")
    st.add_argument("--jitter", type=float, default=0.25, help="half-width of the rating jitter")
    st.add_argument("--n-jitter", type=int, default=10000, help="jitter repetitions")
    st.add_argument("--n-bootstrap", type=int, default=10000, help="bootstrap resamples")
    st.add_argument("--confidence", type=float, default=0.95)
    st.add_argument("--seed", type=int, default=0)
    st.add_argument("--figures", metavar="DIR", help="write the scatter and r-vs-N figures")
    st.add_argument("--report", metavar="SURVEY_DIR",
                    help="(re)write SURVEY_DIR/report.html with these statistics")
    st.add_argument("--output-json", metavar="OUT.json")
    st.add_argument("--json", action="store_true")
    st.set_defaults(func=cmd_study)

    sv = sub.add_parser("survey", help="process every view of a survey manifest (parallel, resumable)")
    sv.add_argument("manifest", help="survey manifest (TOML, schema lsadphoto.survey/1)")
    sv.add_argument("-o", "--output", required=True, help="output folder (rerun to resume)")
    sv.add_argument("--workers", type=int, help="worker processes here (default one per CPU; 0: in this process)")
    sv.add_argument("--dask", metavar="tcp://HOST:PORT", help="use a running Dask scheduler instead")
    sv.add_argument("--N", type=float, help="threshold count N of Q for every view")
    sv.add_argument("--alpha-arcmin", type=float, help="critical detail α [arcmin] for every view")
    sv.add_argument("--quiet", action="store_true", help="no progress bar")
    sv.add_argument("--no-report", action="store_true", help="do not write OUTPUT/report.html")
    sv.add_argument("--json", action="store_true", help="print the JSON summary")
    sv.set_defaults(func=cmd_survey)

    sim = sub.add_parser("simulate", help="Monte Carlo light chains of a scene model → view-independent store")
    sim.add_argument("scene", help="scene model: our TOML, a Radiance scene (.rad) or rad file (.rif)")
    sim.add_argument("-o", "--output", required=True, help="store to write (.npz)")
    sim.add_argument("--samples", type=int, help="light chains (default 65536 unless --target-error)")
    sim.add_argument("--target-error", type=float,
                     help="stop at this relative standard error of the scene's mean luminance (e.g. 0.01)")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--near-field", choices=_Choices("lsadphoto.solver.integrators.local_estimate", "NEAR_FIELD_TREATMENTS"),
                     help="near-field treatment (default: the first; clamp is biased and reported as such)")
    _add_fresnel_rule(sim, "(default reciprocal; recorded in the store, whose renders use it)")
    _add_cache_options(sim)
    sim.add_argument("--surface-cache", action="store_true",
                     help="also store the indirect illuminance on the surfaces (render --estimator cache)")
    sim.add_argument("--quiet", action="store_true", help="no progress bar")
    sim.add_argument("--json", action="store_true")
    sim.set_defaults(func=cmd_simulate)

    ren = sub.add_parser("render", help="render a luminance map of a view from a store or a scene")
    ren.add_argument("source", help="store (.npz) from 'simulate', or a scene (TOML, Radiance .rad or .rif)")
    ren.add_argument("--profile", help="camera profile (TOML) whose lens model is the projection")
    ren.add_argument("--view", metavar="RADIANCE_VIEW", help='Radiance view, e.g. "-vta -vp 1 2 1.2 -vd 1 0 0 -vu 0 0 1 -vh 180 -vv 180" or "-vf room.vf"')
    ren.add_argument("--view-name", help="a [[views]] entry of the scene (default: its first)")
    ren.add_argument("--size", metavar="WxH", help="image size (with --view; with --profile a binning of its size)")
    ren.add_argument("--position", metavar="X,Y,Z", help="eye position [m] (with --profile)")
    ren.add_argument("--line-of-sight", metavar="X,Y,Z", help="optical axis in the scene (with --profile)")
    ren.add_argument("--up", metavar="X,Y,Z", help="up in the scene (with --profile; default 0,0,1)")
    ren.add_argument("--samples", type=int, help="light chains when rendering a scene directly")
    ren.add_argument("--target-error", type=float, metavar="E",
                     help="rendering a scene: simulate and render in rounds until the mean absolute per-pixel "
                          "relative error that the map's uncertainties imply is at most E (default 0.02 for a "
                          "scene without --samples)")
    ren.add_argument("--estimator", choices=_Choices("lsadphoto.solver.rendering", "ESTIMATORS"), default="auto",
                     help="local: the double local estimate per pixel (unbiased reference); cache: direct "
                          "light per pixel, indirect interpolated from a surface cache (the store's, or built) "
                          "— far faster per pixel, with a small interpolation bias (docs/accuracy.md); auto "
                          "(default): the store's cache if it has one, else local; for a scene, local with "
                          "--samples alone, else cache; local for glossy, specular or transmitting materials "
                          "— and says what it chose")
    ren.add_argument("--nodes-per-pixel", default="auto", help="nodes connected per pixel and batch: a number, 'all' or 'auto'")
    _add_fresnel_rule(ren, "(default: a store's own, another is an error; reciprocal for a scene)")
    _add_cache_options(ren)
    ren.add_argument("--seed", type=int, default=0)
    ren.add_argument("-o", "--output", required=True, help="output OpenEXR map (.exr)")
    ren.add_argument("--hdr", help="also write a Radiance HDR map")
    ren.add_argument("--quiet", action="store_true", help="no progress bar")
    ren.add_argument("--json", action="store_true")
    ren.set_defaults(func=cmd_render)
    return parser


#: Allocations between young-generation collections in a process that is one command
#: (default 700): importing numba and loading its kernels allocates millions of objects, and
#: collecting them every 700 cost about a quarter of a ``score`` process (docs/performance.md).
_COMMAND_GC_THRESHOLD = (50_000, 20, 100)


def main(argv=None):
    """Run one command; ``argv`` None (the ``lsadphoto`` console script) means that the process
    ends with it, so the garbage collector runs rarely and not at all over the objects left at
    the end (``gc.freeze``: the interpreter's exit would otherwise traverse them all)."""
    whole_process = argv is None
    if whole_process:
        gc.set_threshold(*_COMMAND_GC_THRESHOLD)
    parser = build_parser()
    _Parser.argv = tuple(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    warnings.showwarning = _warning_line
    try:
        return _run(args)
    finally:
        if whole_process:
            gc.freeze()


def _run(args):
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
