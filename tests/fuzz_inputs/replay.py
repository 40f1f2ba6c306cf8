"""Malformed ``mjccd replay`` inputs: broken trajectories and models, bad options, unsafe outputs.

The trajectories are short ones written here for the repository's arm model
(``models/arm_obstacle.xml``, six hinges) and, for joint quaternions, its
boxing scene (``models/boxing.xml``, free and ball joints), then damaged:
truncated, renamed, given the wrong arrays, dtypes, shapes, numbers or
times.  The models are small MJCF files written here, broken in the ways
MuJoCo accepts silently or refuses.  Outputs point at files and at folders
that hold another run.
"""
import io
import pathlib
import pickle
import zipfile

import numpy as np

from . import FuzzCase

ROOT = pathlib.Path(__file__).resolve().parents[2]
ARM = ROOT / "models" / "arm_obstacle.xml"
BOXING = ROOT / "models" / "boxing.xml"
ARM_NQ, BOXING_NQ = 6, 174


def two_ellipsoids(size="0.2 0.1 0.1", pos="1 0 0", joint="<freejoint/>", extra=""):
    """MJCF text of a free ellipsoid and a fixed one (nq = 7) with any part replaced."""
    return f"""<mujoco>
  <worldbody>
    <body name="a">{joint}<geom name="ea" type="ellipsoid" size="{size}"/></body>
    <body name="b" pos="{pos}"><geom name="eb" type="ellipsoid" size="0.2 0.1 0.1"/></body>
    {extra}
  </worldbody>
</mujoco>
"""


def _npz_bytes(**arrays):
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def _npy_member(header, payload=b""):
    """The bytes of a .npy file with the given header dict (shape, descr) and payload."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, header)
    return buffer.getvalue() + payload


def _zip(members):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return buffer.getvalue()


def _broken_npz_files(rng, qpos, time):
    """(label, file name, bytes) of trajectory files that are not readable .npz archives of arrays."""
    good = _npz_bytes(qpos=qpos, time=time)
    compressed = io.BytesIO()
    np.savez_compressed(compressed, qpos=rng.normal(size=(200, ARM_NQ)), time=np.arange(200.0))
    corrupted = bytearray(compressed.getvalue())
    middle = len(corrupted) // 2
    corrupted[middle:middle + 16] = bytes(rng.integers(0, 256, 16, dtype="u1"))
    npy = io.BytesIO()
    np.save(npy, qpos)
    return [
        ("npz truncated to 10 bytes", "cut10.npz", good[:10]),
        ("npz truncated to half", "cut_half.npz", good[:len(good) // 2]),
        ("npz missing its last byte", "cut_last.npz", good[:-1]),
        ("empty npz", "empty.npz", b""),
        (".npy renamed .npz", "renamed.npz", npy.getvalue()),
        ("text file named .npz", "text.npz", b"qpos = [[0, 0, 0, 0, 0, 0]]\n"),
        ("random bytes named .npz", "noise.npz", bytes(rng.integers(0, 256, 512, dtype="u1"))),
        ("pickle named .npz", "pickled.npz", pickle.dumps({"qpos": qpos, "time": time})),
        ("compressed npz with corrupted data", "corrupt.npz", bytes(corrupted)),
        ("zip member that is not .npy", "notnpy.npz", _zip({"qpos.npy": b"not an array", "time.npy": b"x"})),
        ("zip member without .npy suffix", "rawmember.npz", _zip({"qpos": b"raw bytes"})),
        ("npy header claims a huge array", "huge.npz",
         _zip({"qpos.npy": _npy_member({"descr": "<f8", "fortran_order": False, "shape": (10 ** 12, ARM_NQ)},
                                       b"\0" * 64)})),
        ("npy header with an unknown dtype", "baddescr.npz",
         _zip({"qpos.npy": _npy_member({"descr": "<q9", "fortran_order": False, "shape": (5, ARM_NQ)})})),
        ("npy payload shorter than its header", "short.npz",
         _zip({"qpos.npy": _npy_member({"descr": "<f8", "fortran_order": False, "shape": (5, ARM_NQ)},
                                       b"\0" * 8)})),
    ]


def _bad_arrays(qpos, time):
    """(label, file name, arrays for np.savez) of archives whose arrays are wrong."""
    T = len(time)
    cases = [
        ("no qpos array", "noqpos.npz", {"time": time}),
        ("qpos under another name", "q.npz", {"q": qpos, "time": time}),
        ("an extra array", "extra.npz", {"qpos": qpos, "time": time, "velocity": qpos}),
        ("qpos as text", "str.npz", {"qpos": qpos.astype(str), "time": time}),
        ("qpos as bytes", "bytes.npz", {"qpos": qpos.astype("S8"), "time": time}),
        ("qpos as booleans", "bool.npz", {"qpos": qpos > 0, "time": time}),
        ("complex qpos", "complex.npz", {"qpos": qpos + 1j, "time": time}),
        ("complex64 qpos with zero imaginary part", "complex64.npz", {"qpos": qpos.astype(np.complex64), "time": time}),
        ("qpos as datetimes", "datetime.npz", {"qpos": qpos.astype("datetime64[s]"), "time": time}),
        ("qpos as timedeltas", "timedelta.npz", {"qpos": qpos.astype("timedelta64[s]"), "time": time}),
        ("structured qpos", "structured.npz",
         {"qpos": np.zeros(T, dtype=[("x", "f8", (ARM_NQ,))]), "time": time}),
        ("qpos 1-D", "flat.npz", {"qpos": qpos.ravel(), "time": time}),
        ("qpos 3-D", "cube.npz", {"qpos": qpos[None], "time": time}),
        ("qpos scalar", "scalar.npz", {"qpos": np.float64(1.0), "time": time}),
        ("qpos one column short", "narrow.npz", {"qpos": qpos[:, :-1], "time": time}),
        ("qpos one column too many", "wide.npz", {"qpos": np.hstack([qpos, qpos[:, :1]]), "time": time}),
        ("qpos transposed", "transposed.npz", {"qpos": qpos.T.copy(), "time": np.arange(ARM_NQ) * 0.01}),
        ("qpos with no frames", "noframes.npz", {"qpos": qpos[:0], "time": time[:0]}),
        ("qpos with one frame", "oneframe.npz", {"qpos": qpos[:1], "time": time[:1]}),
        ("qpos with no columns", "nocolumns.npz", {"qpos": qpos[:, :0], "time": time}),
        ("time as text", "timestr.npz", {"qpos": qpos, "time": time.astype(str)}),
        ("complex time", "timecomplex.npz", {"qpos": qpos, "time": time + 0.5j}),
        ("time as booleans", "timebool.npz", {"qpos": qpos, "time": time > 0}),
        ("time one short", "timeshort.npz", {"qpos": qpos, "time": time[:-1]}),
        ("time one too many", "timelong.npz", {"qpos": qpos, "time": np.append(time, time[-1] + 1)}),
        ("time 2-D", "time2d.npz", {"qpos": qpos, "time": time[:, None]}),
        ("time scalar", "timescalar.npz", {"qpos": qpos, "time": np.float64(0.0)}),
        ("time decreasing", "backwards.npz", {"qpos": qpos, "time": time[::-1].copy()}),
        ("time constant", "constant.npz", {"qpos": qpos, "time": np.zeros(T)}),
        ("time with a repeated value", "repeat.npz", {"qpos": qpos, "time": np.r_[time[:2], time[1], time[3:]]}),
        ("time with one step back", "stepback.npz", {"qpos": qpos, "time": np.r_[time[:3], time[1], time[4:]]}),
        ("keyframes of the wrong width", "keywidth.npz",
         {"qpos": qpos, "time": time, "keyframes": qpos[:2, :-1]}),
    ]
    for value, name in ((np.nan, "nan"), (np.inf, "inf"), (-np.inf, "neginf"), (1e300, "1e300"),
                        (-1e7, "neg1e7"), (1e6 * (1 + 1e-15), "just above 1e6")):
        for frame in (0, T - 1):
            bad = qpos.copy()
            bad[frame, frame % ARM_NQ] = value
            cases.append((f"qpos {name} in frame {frame}", f"qpos_{name.replace(' ', '_')}_{frame}.npz",
                          {"qpos": bad, "time": time}))
    for value, name in ((np.nan, "nan"), (np.inf, "inf"), (-np.inf, "neginf"), (1e300, "1e300"), (-1e13, "neg1e13")):
        bad = time.copy()
        bad[-1] = value
        cases.append((f"time {value:g} in the last frame", f"time_{name}.npz", {"qpos": qpos, "time": bad}))
    return cases


def _zero_quaternions(qpos, time):
    """(label, file name, arrays) of boxing trajectories with a free or ball joint quaternion of zero length."""
    cases = []
    for label, columns, frame in (("free joint of boxer a", slice(3, 7), 1),
                                  ("free joint of boxer b", slice(BOXING_NQ // 2 + 3, BOXING_NQ // 2 + 7), 0),
                                  ("first ball joint", slice(7, 11), 2),
                                  ("last ball joint", slice(BOXING_NQ - 4, BOXING_NQ), 3)):
        bad = qpos.copy()
        bad[frame, columns] = 0.0
        cases.append((f"zero quaternion, {label}, frame {frame}", f"zeroquat_{columns.start}.npz",
                      {"qpos": bad, "time": time}))
    tiny = qpos.copy()
    tiny[0, 7:11] = 1e-300
    cases.append(("quaternion of length 2e-300", "tinyquat.npz", {"qpos": tiny, "time": time}))
    return cases


def _bad_models():
    """(label, file name, MJCF text or bytes) of models replay must refuse."""
    return [
        ("empty model file", "empty.xml", ""),
        ("binary model file", "binary.xml", b"\x00\xff\xfe" * 50),
        ("truncated MJCF", "cut.xml", two_ellipsoids()[:60]),
        ("not MJCF", "html.xml", "<html><body>hello</body></html>"),
        ("unknown element", "unknown.xml", two_ellipsoids(extra="<spaceship/>")),
        ("include of a missing file", "include.xml", "<mujoco><include file='nowhere.xml'/></mujoco>"),
        ("mesh file missing", "nomesh.xml", ARM.read_text()),
        ("ellipsoid of size 1e300", "huge.xml", two_ellipsoids(size="1e300 0.1 0.1")),
        ("ellipsoid of size inf", "inf.xml", two_ellipsoids(size="inf 0.1 0.1")),
        ("ellipsoid of size nan", "nan.xml", two_ellipsoids(size="nan 0.1 0.1")),
        ("ellipsoid of size 1e-9", "tiny.xml", two_ellipsoids(size="1e-9 1 1")),
        ("ellipsoid of negative size", "negative.xml", two_ellipsoids(size="-1 0.1 0.1")),
        ("one ellipsoid", "one.xml", "<mujoco><worldbody><body><freejoint/>"
                                     "<geom type='ellipsoid' size='1 1 1'/></body></worldbody></mujoco>"),
        ("no ellipsoid", "spheres.xml", two_ellipsoids().replace("ellipsoid", "sphere")),
        ("nothing moves", "still.xml", two_ellipsoids(joint="")),
        ("body 1e300 m away", "far.xml", two_ellipsoids(pos="1e300 0 0")),
    ]


def generate(folder, rng):
    folder = pathlib.Path(folder)
    cases = []
    with np.load(ROOT / "data" / "arm_traj.npz") as d:
        qpos, time, keys = d["qpos"][:5].copy(), d["time"][:5].copy(), d["keyframes"].copy()
    with np.load(ROOT / "data" / "boxing_traj.npz") as d:
        box_qpos, box_time = d["qpos"][136:140].copy(), d["time"][136:140].copy()
    np.savez(folder / "arm.npz", qpos=qpos, time=time)
    np.savez(folder / "two.npz", qpos=np.tile([0, 0, 0, 1, 0, 0, 0.0], (4, 1)), time=np.arange(4) * 0.01)
    arm, model = "arm.npz", str(ARM)

    for label, name, data in _broken_npz_files(rng, qpos, time):
        (folder / name).write_bytes(data)
        cases.append(FuzzCase(label, ["replay", model, name, "--no-render"], (name,)))
    for label, name, arrays in _bad_arrays(qpos, time):
        np.savez(folder / name, **arrays)
        argv = ["replay", model, name, "--no-render"] + (["--intervals"] if "keyframes" in arrays else [])
        cases.append(FuzzCase(label, argv, (name,)))
    for label, name, arrays in _zero_quaternions(box_qpos, box_time):
        np.savez(folder / name, **arrays)
        cases.append(FuzzCase(label, ["replay", str(BOXING), name, "--no-render"], (name,)))

    # a hinge may stand anywhere, but beyond pi the chain motion cannot follow a turn of pi or more in one frame
    wrapped = qpos.copy()
    wrapped[2, 3] = wrapped[1, 3] + 4.0
    np.savez(folder / "wrapped.npz", qpos=wrapped, time=time)
    cases.append(FuzzCase("hinge turning by 4 rad in a frame with the chain motion",
                          ["replay", model, "wrapped.npz", "--motion", "chain", "--no-render"], ("wrapped.npz",)))
    wrapped_keys = keys.copy()
    wrapped_keys[0, 0], wrapped_keys[1, 0] = 0.0, -4.0
    np.savez(folder / "keywrap.npz", qpos=qpos, time=time, keyframes=wrapped_keys)
    cases.append(FuzzCase("keyframe hinge turning by 4 rad", ["replay", model, "keywrap.npz", "--intervals",
                                                              "--no-render"], ("keywrap.npz",)))
    nan_keys = keys.copy()
    nan_keys[0, 2] = np.nan
    np.savez(folder / "keynan.npz", qpos=qpos, time=time, keyframes=nan_keys)
    cases.append(FuzzCase("keyframes with NaN", ["replay", model, "keynan.npz", "--intervals", "--no-render"],
                          ("keynan.npz",)))
    np.savez(folder / "keycomplex.npz", qpos=qpos, time=time, keyframes=keys + 1j)
    cases.append(FuzzCase("complex keyframes", ["replay", model, "keycomplex.npz", "--intervals", "--no-render"],
                          ("keycomplex.npz",)))
    cases.append(FuzzCase("--intervals without keyframes", ["replay", model, arm, "--intervals", "--no-render"],
                          (arm,)))

    (folder / "clip.bvh").write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n")
    (folder / "empty.bvh").write_text("")
    (folder / "traj.csv").write_text("0,0,0,0,0,0\n")
    (folder / "trajdir").mkdir()
    for label, name in (("truncated BVH clip", "clip.bvh"), ("empty BVH clip", "empty.bvh"),
                        ("CSV trajectory", "traj.csv"), ("trajectory is a folder", "trajdir"),
                        ("trajectory missing", "missing.npz"), ("trajectory without suffix", "missing")):
        cases.append(FuzzCase(label, ["replay", model, name, "--no-render"], (name,)))
    cases.append(FuzzCase("--intervals with a BVH clip", ["replay", model, "clip.bvh", "--intervals", "--no-render"],
                          ("clip.bvh",)))

    for label, name, text in _bad_models():
        (folder / name).write_bytes(text if isinstance(text, bytes) else text.encode())
        cases.append(FuzzCase(label, ["replay", name, "two.npz", "--no-render", "--out", "out"], (name,)))
    for label, name in (("model missing", "missing.xml"), ("model is a folder", "trajdir"),
                        ("model is the trajectory", arm)):
        cases.append(FuzzCase(label, ["replay", name, arm, "--no-render"], (name,)))
    cases.append(FuzzCase("model and trajectory swapped", ["replay", arm, model, "--no-render"], (arm,)))

    for value in ("spline", "", "RIGID", "rigid ", "chain,rigid"):
        cases.append(FuzzCase(f"--motion {value!r}", ["replay", model, arm, "--motion", value], ("--motion",)))
    for value in ("-1", "-100000000000000000000", "nan", "inf", "-inf", "1e30", "3.5", "", "abc", "0x10"):
        cases.append(FuzzCase(f"--rows {value!r}", ["replay", model, arm, "--rows", value], ("--rows",)))
    cases += [
        FuzzCase("no arguments", ["replay"], ("model",)),
        FuzzCase("no trajectory", ["replay", model], ("traj",)),
        FuzzCase("an extra argument", ["replay", model, arm, "arm2.npz"], ("arm2.npz",)),
        FuzzCase("unknown option", ["replay", model, arm, "--bogus"], ("--bogus",)),
        FuzzCase("--out without a folder", ["replay", model, arm, "--out"], ("--out",)),
        FuzzCase("--out empty", ["replay", model, arm, "--no-render", "--out", ""], ("--out",)),
        FuzzCase("--force with a value", ["replay", model, arm, "--force=yes"], ("--force",)),
    ]

    (folder / "used").mkdir()
    (folder / "used" / "notes.txt").write_text("someone else's file\n")
    (folder / "earlier").mkdir()
    for name in ("contacts.json", "contacts.csv", "timeline.png", "frame_00001.png"):
        (folder / "earlier" / name).write_text("from an earlier run\n")
    (folder / "earlier" / ".mjccd-manifest.json").write_text('{"tool": "replay", "files": ["contacts.json"]}\n')
    for label, out in (("--out is the trajectory", arm), ("--out is the model", model),
                       ("--out is a file in a folder", "used/notes.txt"), ("--out under a file", f"{arm}/out"),
                       ("--out into a folder of other files", "used"), ("--out into an earlier run", "earlier"),
                       ("--out into the working folder", ".")):
        cases.append(FuzzCase(label, ["replay", model, arm, "--no-render", "--out", out], (out,)))
    cases.append(FuzzCase("--force onto a file", ["replay", model, arm, "--no-render", "--force", "--out", arm],
                          (arm,)))
    return cases
