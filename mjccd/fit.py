"""``mjccd fit``: bounding ellipsoids of a MuJoCo model's bodies, written into a copy of the model and a file.

The fit itself is :func:`mjccd.mujoco.ellipsoids.fit_model` (its maths in
:mod:`mjccd.fitting`); this module reads MJCF files, adds the ellipsoids to
the model as visual-only geoms through ``MjSpec``, and is the command line.
"""
import argparse
import contextlib
import os
import sys
import tempfile
import warnings

import mujoco

from mjccd import _command, files
from mjccd.errors import InputError, MjccdError
from mjccd.fitting import DEFAULT_TOLERANCE, MAX_ELLIPSOIDS, SURFACE_SAMPLES, VOLUME_SAMPLES
from mjccd.mujoco import ellipsoids as fitted  # fit_model's one public path is mjccd.mujoco.fit_model
from mjccd.mujoco.warnings import CoverageWarning, mujoco_warnings

VISUAL_GROUP = 5
VISUAL_RGBA = (0.2, 0.6, 1.0, 0.3)
# Names of the geoms written by :func:`write_mjcf`; a model read back drops them (see :func:`_load`).
GEOM_PREFIX = "mjccd_ellipsoid_"
# The default class of those geoms: MuJoCo's own geom defaults, so that nothing of the model's classes
# (a fromto, a mass, a fluid shape) reaches them.
GEOM_CLASS = "mjccd_ellipsoid"


def volume_report(ellipsoids, report=None):
    """Plain-text tables: per ellipsoid its body, geom, radii and volume ratio; per body a :func:`fit_report`.

    Args:
        ellipsoids: :class:`~mjccd.mujoco.EllipsoidSet`.
        report: the tuple :func:`~mjccd.mujoco.ellipsoids.fit_report` returns, or None for the first table only.
    """
    lines = [f"{'body':<24} {'geom':<16} {'radii':<30} {'volume ratio':>12}"]
    for b, g, r, v in zip(ellipsoids.bodies, ellipsoids.geoms, ellipsoids.radii, ellipsoids.volume_ratios):
        radii = " ".join(f"{x:.4g}" for x in r)
        lines.append(f"{b:<24} {g or '-':<16} {radii:<30} {v:>12.3f}")
    if report is not None:
        lines += ["", f"{'body':<24} {'ellipsoids':>10} {'overshoot':>12} {'union volume ratio':>19}"]
        for row in report:
            overshoot = row.overshoot if row.overshoot > 1e-12 else 0.0  # rounding of an exact fit
            lines.append(f"{row.body:<24} {row.ellipsoids:>10d} {overshoot:>12.4g} {row.volume_ratio:>19.3f}")
        worst = max(report, key=lambda row: row.overshoot)
        lines.append(f"{len(ellipsoids)} ellipsoids on {len(report)} bodies; largest overshoot {worst.overshoot:.4g} "
                     f"({worst.body})")
        lines.append(f"overshoot: the farthest point of a body's ellipsoids from its geometry (model units), over "
                     f"{SURFACE_SAMPLES} points on each ellipsoid's surface, refined, and the Halton points inside; "
                     f"union volume ratio: volume of the ellipsoids over volume of the geometry, overlaps counted "
                     f"once, from {VOLUME_SAMPLES} Halton points")
    return "\n".join(lines)


# ---------------------------------------------------------------- MJCF output


def _one_line(exc):
    return " ".join(str(exc).split())


def _load(model_path):
    """``(spec, compiled model)`` of an MJCF file, less the ellipsoid geoms an earlier fit added.

    So fitting a fitted model replaces its ellipsoids: they are neither
    bounded themselves nor added a second time.  Errors name the file.
    """
    try:
        spec = mujoco.MjSpec.from_file(os.fspath(model_path))
    except ValueError as exc:
        raise InputError(f"{model_path}: MuJoCo cannot load it: {_one_line(exc)}") from None
    earlier = [geom for geom in spec.geoms if geom.name.startswith(GEOM_PREFIX)]
    for geom in earlier:
        spec.delete(geom)
    try:
        return spec, spec.compile()
    except ValueError as exc:
        without = f" without its {len(earlier)} {GEOM_PREFIX}* geoms" if earlier else ""
        raise InputError(f"{model_path}: MuJoCo cannot compile it{without}: {_one_line(exc)}") from None


def load_model(model_path):
    """The compiled model of an MJCF file, less the ellipsoids an earlier fit added (see :func:`_load`)."""
    return _load(model_path)[1]


def mjcf_with_ellipsoids(model_path, ellipsoids, output_path, *, group=VISUAL_GROUP, rgba=VISUAL_RGBA):
    """MJCF text of the model with the ellipsoids added as visual-only geoms, to be saved at ``output_path``.

    The geoms have ``contype = conaffinity = 0``, zero mass and density, their
    own ``group`` (hidden or shown with the viewer's group toggles) and their
    own default class (:func:`_clean_class`: nothing of the model's defaults
    reaches them), so the simulation is unchanged.  Ellipsoids of an earlier
    fit are replaced.  ``meshdir`` and ``texturedir`` (``assetdir`` sets both)
    are rewritten relative to ``output_path`` and the model is compiled from
    there, as MuJoCo will read the file; included files are written inline.
    """
    spec, model = _load(model_path)
    ids = ellipsoids.body_ids(model)
    clean = _clean_class(spec, group, rgba)
    for k, (bid, r, p, q) in enumerate(zip(ids, ellipsoids.radii, ellipsoids.positions, ellipsoids.quaternions)):
        body = spec.worldbody if bid == 0 else spec.bodies[bid]
        geom = body.add_geom(default=clean)
        geom.name = f"{GEOM_PREFIX}{k}"
        geom.size = r
        geom.pos = p
        geom.quat = q
    src_dir = os.path.dirname(os.path.abspath(model_path))
    out_dir = os.path.dirname(os.path.abspath(output_path))
    if src_dir != out_dir:
        for attr in ("meshdir", "texturedir"):
            value = getattr(spec, attr)
            if not os.path.isabs(value or ""):
                setattr(spec, attr, os.path.relpath(os.path.join(src_dir, value or ""), out_dir))
        spec.modelfiledir = out_dir + os.sep  # assets are now found from the output's folder
    try:
        return spec.to_xml()  # compiles the model again, with the ellipsoids
    except ValueError as exc:
        raise InputError(f"{model_path}: MuJoCo cannot compile it with the ellipsoids added: "
                         f"{_one_line(exc)}") from None


# every geom attribute a default class can set, reset to MuJoCo's built-in value in :data:`GEOM_CLASS`
_GEOM_DEFAULTS = ("type", "size", "fromto", "contype", "conaffinity", "condim", "priority", "friction", "solmix",
                  "solref", "solimp", "margin", "gap", "surfacevel", "adhesion", "mass", "density", "typeinertia",
                  "fluid_ellipsoid", "fluid_coefs", "material", "rgba", "group", "hfieldname", "meshname", "fitscale")


def _clean_class(spec, group, rgba):
    """The default class :data:`GEOM_CLASS` of ``spec`` for the ellipsoids (made, or reset after an earlier fit).

    A geom added to a body takes the body's child class, and a class can set
    ``fromto`` (which then clashes with the ellipsoid's ``pos``), a mass, a
    fluid shape, a material.  The ellipsoids get a class of their own whose
    geom defaults are MuJoCo's built-in ones, plus what makes them visual-only
    and massless; written to MJCF it keeps them so when the file is read back.
    """
    clean = spec.find_default(GEOM_CLASS) or spec.add_default(GEOM_CLASS, spec.default)
    pristine = mujoco.MjSpec().worldbody.add_geom()
    for name in _GEOM_DEFAULTS:
        setattr(clean.geom, name, getattr(pristine, name))
    clean.geom.userdata = []
    clean.geom.type = mujoco.mjtGeom.mjGEOM_ELLIPSOID
    clean.geom.contype = 0
    clean.geom.conaffinity = 0
    clean.geom.density = 0.0  # massless; the mass stays unset: MuJoCo writes no density for a class with a mass
    clean.geom.group = group
    clean.geom.rgba = rgba
    return clean


def write_mjcf(model_path, ellipsoids, output_path, *, group=VISUAL_GROUP, rgba=VISUAL_RGBA):
    """Write :func:`mjcf_with_ellipsoids` to ``output_path`` (atomically: the old file or the new, never half)."""
    files.write_text(output_path, mjcf_with_ellipsoids(model_path, ellipsoids, output_path, group=group, rgba=rgba))


def _ellipsoid_file_bytes(ellipsoids, name):
    """The bytes :meth:`EllipsoidSet.save` writes for a file called ``name`` (.json or .npz)."""
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, os.path.basename(name))
        ellipsoids.save(path)
        with open(path, "rb") as fh:
            return fh.read()


# ---------------------------------------------------------------- command line

DESCRIPTION = f"""\
Bound the bodies of a MuJoCo model by ellipsoids, report how tightly, and
write the model with the ellipsoids added as visual-only geoms named
mjccd_ellipsoid_<k> (-o) and the ellipsoids themselves (--ellipsoids).  By
default each geom is covered by as few ellipsoids as keep every point of them
within --tolerance ({DEFAULT_TOLERANCE:g} m) of the geom, a body's geoms sharing one
ellipsoid where that stays within it; --tolerance none fits one ellipsoid per
body (or per geom with --per geom), fewer but looser.  Every point of the
bounded geoms lies inside the ellipsoids either way.  A model that already has
geoms named mjccd_ellipsoid_* (the output of an earlier fit) is refitted:
those geoms are dropped before the fit and replaced, never bounded and never
duplicated.  Existing files, and the model itself, are replaced only with
--force; both outputs appear together or not at all."""


def _output_paths(args):
    """The MJCF output and the ellipsoid file to write (each None when not asked for), checked before the fit."""
    if not 0 <= args.group <= 5:
        raise InputError(f"--group: must be in 0..5, got {args.group}")
    target = args.ellipsoids or (os.path.splitext(args.output)[0] + ".ellipsoids.json" if args.output else None)
    if target and not target.endswith((".json", ".npz")):
        raise InputError(f"--ellipsoids: expected a .json or .npz file name, got {target!r}")
    if target and args.output and os.path.realpath(target) == os.path.realpath(args.output):
        raise InputError(f"--ellipsoids: {target} is also the -o model file; give two different names")
    for path in (args.output, target):
        if path:
            files.check_output_file(path, inputs=[args.model], force=args.force)
    return args.output, target


def main(argv=None):
    """``mjccd fit MODEL.xml -o OUT.xml``: fit, report volume ratios, write MJCF and an ellipsoid file."""
    parser = argparse.ArgumentParser(formatter_class=_command.PlainHelpFormatter,
                                     prog="mjccd fit", description=DESCRIPTION)
    parser.add_argument("model", help="MJCF model file")
    parser.add_argument("-o", "--output", help="MJCF file with the ellipsoids added as visual geoms")
    parser.add_argument("--ellipsoids", help="ellipsoid file to write (.json or .npz); "
                        "default: next to --output with extension .ellipsoids.json")
    parser.add_argument("--tolerance", type=_tolerance, default=DEFAULT_TOLERANCE, metavar="METRES",
                        help=f"the farthest a point of the ellipsoids may lie from the geometry, in the model's "
                        f"length unit (default {DEFAULT_TOLERANCE:g}, 1 cm in metres); 'none': one ellipsoid per "
                        f"body or geom (--per)")
    parser.add_argument("--per", choices=("body", "geom"), default="body",
                        help="with a tolerance: 'body' lets a body's geoms share one ellipsoid where that stays "
                        "within it; without: one ellipsoid per body or per geom (default body)")
    parser.add_argument("--max-ellipsoids", type=int, default=MAX_ELLIPSOIDS, metavar="N",
                        help=f"refuse a geom that needs more ellipsoids than this at the tolerance "
                        f"(default {MAX_ELLIPSOIDS})")
    parser.add_argument("--bodies", nargs="+", help="only these bodies")
    parser.add_argument("--include-visual", action="store_true", help="also bound non-colliding geoms")
    parser.add_argument("--group", type=int, default=VISUAL_GROUP, help="geom group of the ellipsoids")
    parser.add_argument("--force", action="store_true", help="replace existing output files (even MODEL)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no report")
    parser.add_argument("--render", metavar="PNG",
                        help="also draw the written model (-o) with its ellipsoids into this picture (skipped, "
                        "with one line, where OpenGL is missing)")
    args = parser.parse_args(argv)
    written = []
    try:
        with mujoco_warnings(lambda text: print(f"mjccd fit: {args.model}: MuJoCo warns: {text}",
                                                file=sys.stderr)):
            model = load_model(args.model)
            output, target = _output_paths(args)
            written = [p for p in (output, target) if p]
            if args.render:
                if not output:
                    raise InputError("--render: draws the written model, so it needs -o OUT.xml")
                files.check_output_file(args.render, inputs=[args.model, output], force=args.force)
            try:
                if args.max_ellipsoids < 1:
                    raise InputError(f"--max-ellipsoids: expected a positive integer, got {args.max_ellipsoids}")
                with warnings.catch_warnings(record=True) as notes:  # printed below, in the command's words
                    warnings.simplefilter("always", CoverageWarning)
                    ellipsoids = fitted.fit_model(model, tolerance=args.tolerance, per=args.per, bodies=args.bodies,
                                           include_visual=args.include_visual, max_ellipsoids=args.max_ellipsoids)
                if len(ellipsoids) == 0:
                    raise ValueError("no body has sphere, capsule, ellipsoid, cylinder, box or mesh collision "
                                     "geometry: nothing to bound" + ("" if args.include_visual else
                                                                     " (--include-visual bounds the visual geoms)"))
                for note in notes:  # geoms covered within a looser tolerance
                    print(f"mjccd fit: {args.model}: {str(note.message).removeprefix('fit_model: ')}",
                          file=sys.stderr)
                report = None if args.quiet else fitted.fit_report(model, ellipsoids,
                                                                   include_visual=args.include_visual)
            except ValueError as exc:
                raise InputError(f"{args.model}: {exc}") from None
            xml = mjcf_with_ellipsoids(args.model, ellipsoids, output, group=args.group) if output else None
        data = _ellipsoid_file_bytes(ellipsoids, target) if target else None
        # both files are renamed into place only once both are complete
        with contextlib.ExitStack() as stack:
            if output:
                stack.enter_context(files.atomic_open(output, "w", encoding="utf-8")).write(xml)
            if target:
                stack.enter_context(files.atomic_open(target, "wb")).write(data)
    except (MjccdError, ValueError, OSError) as exc:
        return _command.failure("fit", exc, written)
    if args.render:
        try:
            render_fit(output, args.render, group=args.group)
        except (MjccdError, ValueError, OSError) as exc:
            return _command.failure("fit", exc, [args.render])
    if not args.quiet:
        print(volume_report(ellipsoids, report))
    return 0


def render_fit(model_path, png, *, group=VISUAL_GROUP, height=720, width=960):
    """Draw the model at ``model_path`` (its first keyframe, else ``qpos0``) with geom group ``group`` shown into
    the picture ``png``, written whole or not at all; returns False (after one line) where OpenGL is missing."""
    from matplotlib.image import imsave

    from mjccd.mujoco.render import open_renderer, scene_option, whole_model_camera

    model = mujoco.MjModel.from_xml_path(str(model_path))  # as written, ellipsoids included
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    renderer = open_renderer(model, height, width)
    if renderer is None:
        return False
    try:
        data = mujoco.MjData(model)
        if model.nkey:
            mujoco.mj_resetDataKeyframe(model, data, 0)
        mujoco.mj_forward(model, data)
        renderer.update_scene(data, whole_model_camera(model, data), scene_option(group))
        with files.atomic_open(png, "wb") as fh:
            imsave(fh, renderer.render(), format="png")
    finally:
        renderer.close()
    return True


def _tolerance(text):
    """``--tolerance``: a positive length, or ``none``."""
    if text.strip().lower() == "none":
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive length or 'none', got {text!r}")
    return value


if __name__ == "__main__":
    sys.exit(main())
