"""The pairs every MuJoCo path checks (mjccd.mujoco.pairs) against MuJoCo's own collision detection.

The oracle is MuJoCo itself: a copy of the model with every geom's margin at 1 km (gap 0), so that its
bounding-sphere test and its contact functions keep every geom pair its filters pass, and with the
midphase off (the BVH tree of a body's geoms ignores the margin).  One ``mj_forward`` at ``qpos0`` then
lists, in ``data.contact``, every geom pair MuJoCo's collision driver considers: its broadphase, weld,
static, parent-child, contype/conaffinity, ``<exclude>`` and ``<pair>`` rules, none of them copied here.
"""
import copy
import pathlib
import re
import warnings

import mujoco
import numpy as np
import pytest

from mjccd import cli
from mjccd.errors import InputError
from mjccd.mujoco import CCDMonitor, fit_model, geom_ellipsoids
from mjccd.mujoco import monitor as monitor_module
from mjccd.mujoco.pairs import (bounded_geoms, default_pairs, plane_pairs, select_pairs, self_pairs,
                                uncovered_geoms, warn_uncovered)
from mjccd.mujoco.warnings import CoverageWarning

pytestmark = pytest.mark.mujoco

ROOT = pathlib.Path(__file__).resolve().parents[1]
PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)
HFIELD = int(mujoco.mjtGeom.mjGEOM_HFIELD)
SDF = int(mujoco.mjtGeom.mjGEOM_SDF)
SUITE = [("humanoid", "stand"), ("humanoid_CMU", "stand"), ("walker", "walk"), ("quadruped", "walk"),
         ("quadruped", "escape"), ("manipulator", "bring_ball"), ("cheetah", "run"), ("cartpole", "swingup")]


# ---------------------------------------------------------------- the oracle: MuJoCo's own collision driver


def mujoco_geom_pairs(model):
    """Every geom pair (low id, high id) MuJoCo's collision driver would collide in ``model``, at qpos0."""
    m = copy.deepcopy(model)
    m.geom_margin[:] = 1e3
    m.geom_gap[:] = 0.0
    if m.npair:
        m.pair_margin[:] = 1e3
        m.pair_gap[:] = 0.0
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_MIDPHASE)
    # contacts switched off globally: mjccd keeps the pairs the rules collide (see mjccd.mujoco.pairs)
    m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert d.warning[mujoco.mjtWarning.mjWARN_CONTACTFULL].number == 0
    return {tuple(sorted((int(c.geom1), int(c.geom2)))) for c in d.contact[:d.ncon]}


def oracle(model, ellipsoids):
    """MuJoCo's own pairs in mjccd's terms: ``(ellipsoid pairs, (ellipsoid, plane) rows, {geom: ellipsoids})``.

    Each ellipsoid stands for the geoms :func:`bounded_geoms` names (one geom, or its body's bounded
    geoms); contacts with a static plane become plane rows, contacts with a height field, an SDF or a
    plane that moves (with a mocap body) the third item.  Plane-plane, plane-hfield and the other pairs
    without a contact function give no contact in MuJoCo; no ellipsoid stands for a plane, so mjccd never
    selects them either.  Geoms of bodies without an ellipsoid are left out on both sides.
    """
    owners = {}
    for k, geoms in enumerate(bounded_geoms(model, ellipsoids)):
        for g in geoms.tolist():
            owners.setdefault(g, []).append(k)
    pairs, planes, others = set(), set(), {}
    for g1, g2 in mujoco_geom_pairs(model):
        for i in owners.get(g1, ()):
            for j in owners.get(g2, ()):
                if i != j:
                    pairs.add((min(i, j), max(i, j)))
        for unbounded, bounded in ((g1, g2), (g2, g1)):
            kind = model.geom_type[unbounded]
            if unbounded in owners or kind not in (PLANE, HFIELD, SDF):  # else: a body the user left out
                continue
            static_plane = kind == PLANE and model.body_weldid[model.geom_bodyid[unbounded]] == 0
            for i in owners.get(bounded, ()):
                if static_plane:
                    planes.add((i, unbounded))
                else:  # a height field, an SDF, a plane on a moving body
                    others.setdefault(unbounded, set()).add(i)
    return pairs, planes, others


def ours(model, ellipsoids):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CoverageWarning)
        pairs = {tuple(map(int, p)) for p in default_pairs(model, ellipsoids, drop_overlapping_at_qpos0=False)}
    planes = {tuple(map(int, p)) for p in plane_pairs(model, ellipsoids)}
    others = {u.geom: set(u.ellipsoids) for u in uncovered_geoms(model, ellipsoids)}
    return pairs, planes, others


def assert_same_as_mujoco(model, ellipsoids):
    """default_pairs, plane_pairs and uncovered_geoms equal what MuJoCo collides; returns the pair counts."""
    want, got = oracle(model, ellipsoids), ours(model, ellipsoids)
    names = ellipsoids.bodies
    for label, w, g in zip(("pairs", "plane rows", "uncovered geoms"), want, got):
        assert g == w, (f"{label}: only mjccd {sorted(set(g) - set(w))[:8]}, only MuJoCo {sorted(set(w) - set(g))[:8]} "
                        f"(ellipsoids {names})")
    return len(want[0]), len(want[1])


def _suite_model(domain, task):
    from dm_control import suite

    return copy.deepcopy(suite.load(domain, task, task_kwargs={"random": 0}).physics.model.ptr)


@pytest.mark.dm_control
@pytest.mark.parametrize("domain,task", SUITE)
@pytest.mark.parametrize("per", ["body", "geom"])
def test_default_pairs_equal_mujocos_on_the_suite(domain, task, per):
    model = _suite_model(domain, task)
    n_pairs, n_planes = assert_same_as_mujoco(model, fit_model(model, per=per))
    assert n_planes > 0  # every suite model has a floor its bodies touch
    if domain != "walker":  # the walker's limbs have conaffinity 0: they touch the floor only
        assert n_pairs > 0


@pytest.mark.parametrize("name", ["boxing.xml", "arm_obstacle.xml"])
def test_default_pairs_equal_mujocos_on_the_repo_models(name):
    model = mujoco.MjModel.from_xml_path(str(ROOT / "models" / name))
    # every geom there has contype = conaffinity = 0 (visual skins and bounds): MuJoCo collides nothing
    assert assert_same_as_mujoco(model, geom_ellipsoids(model)) == (0, 0)
    spec = mujoco.MjSpec.from_file(str(ROOT / "models" / name))
    for geom in spec.geoms:
        if geom.group != 5:  # the skins collide, the bounding ellipsoids stay visual
            geom.contype, geom.conaffinity = 1, 1
    model = spec.compile()
    for ellipsoids in (geom_ellipsoids(model), fit_model(model, per="geom")):
        n_pairs, n_planes = assert_same_as_mujoco(model, ellipsoids)
        assert n_pairs > 0 and n_planes > 0


# ---------------------------------------------------------------- each rule, on small models

RULES = """
<mujoco>
  <option gravity="0 0 0">{flags}</option>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="post" pos="2 0 0"><geom name="post" type="box" size="0.1 0.1 1"/></body>
    <body name="a" pos="0 0 1"><freejoint/><geom name="a" size="0.1"/>
      <body name="b" pos="0.3 0 0"><joint type="hinge"/><geom name="b" size="0.1"/>
        <body name="c" pos="0.3 0 0"><joint type="hinge"/><geom name="c" size="0.1"/>
          <body name="c_tip" pos="0.2 0 0"><geom name="c_tip" size="0.05"/></body>
        </body>
      </body>
    </body>
    <body name="ghost" pos="0 2 1"><freejoint/><geom name="ghost" size="0.1" contype="0" conaffinity="0"/></body>
    <body name="odd" pos="0 -2 1"><freejoint/><geom name="odd" size="0.1" contype="2" conaffinity="2"/></body>
    <body name="hand" mocap="true" pos="1 1 1"><geom name="hand" size="0.1"/></body>
  </worldbody>
  <contact>{contact}</contact>
</mujoco>
"""


def _model(flags="", contact=""):
    return mujoco.MjModel.from_xml_string(RULES.format(flags=flags, contact=contact))


def _body_pairs(model, ellipsoids, pairs):
    return {tuple(sorted((ellipsoids.bodies[i], ellipsoids.bodies[j]))) for i, j in pairs}


def _default_body_pairs(model, ellipsoids=None):
    ellipsoids = fit_model(model, include_visual=True) if ellipsoids is None else ellipsoids
    assert_same_as_mujoco(model, ellipsoids)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CoverageWarning)
        pairs = default_pairs(model, ellipsoids, drop_overlapping_at_qpos0=False)
    return _body_pairs(model, ellipsoids, pairs)


def test_each_of_mujocos_body_rules():
    pairs = _default_body_pairs(_model())
    assert ("a", "b") not in pairs and ("b", "c") not in pairs  # parent and child
    assert ("c", "c_tip") not in pairs and ("b", "c_tip") not in pairs  # one weld body; its parent
    assert ("a", "c") in pairs and ("a", "c_tip") in pairs
    assert not any("ghost" in p for p in pairs)  # contype = conaffinity = 0
    assert not any("odd" in p for p in pairs)  # contype 2 meets only conaffinity 2
    assert ("hand", "post") not in pairs  # neither can move: a mocap body and a static one
    assert ("a", "hand") in pairs and ("a", "post") in pairs


def test_exclude_removes_and_filterparent_adds():
    assert ("a", "c") not in _default_body_pairs(_model(contact='<exclude body1="c" body2="a"/>'))
    pairs = _default_body_pairs(_model(flags='<flag filterparent="disable"/>'))
    assert {("a", "b"), ("b", "c"), ("b", "c_tip")} <= pairs
    assert ("c", "c_tip") not in pairs  # one rigid body: never collided


def test_explicit_pairs_are_collided_whatever_the_filters():
    contact = ('<pair geom1="ghost" geom2="a"/><pair geom1="b" geom2="c"/><pair geom1="odd" geom2="floor"/>'
               '<exclude body1="a" body2="c"/><pair geom1="c" geom2="a"/>')
    model = _model(contact=contact)
    ellipsoids = fit_model(model, include_visual=True)
    pairs = _default_body_pairs(model, ellipsoids)
    assert {("a", "ghost"), ("b", "c"), ("a", "c")} <= pairs
    planes = {(ellipsoids.bodies[i], int(g)) for i, g in plane_pairs(model, ellipsoids)}
    assert ("odd", 0) in planes and ("ghost", 0) not in planes


@pytest.mark.parametrize("flag", ['<flag contact="disable"/>', '<flag constraint="disable"/>'])
def test_disabled_contacts_keep_the_pairs(flag):
    """MuJoCo resolves no contact with these switches, but the pairs its rules collide are still checked:
    a model whose bodies pass through each other is where continuous detection is wanted."""
    plain = _model(contact='<pair geom1="a" geom2="c"/>')
    switched = _model(flags=flag, contact='<pair geom1="a" geom2="c"/>')
    ellipsoids = fit_model(plain, include_visual=True)
    assert np.array_equal(select_pairs(switched, ellipsoids, None), select_pairs(plain, ellipsoids, None))
    assert len(select_pairs(switched, ellipsoids, None)) > 0
    assert np.array_equal(plane_pairs(switched, ellipsoids), plane_pairs(plain, ellipsoids))


def test_an_ellipsoid_of_one_geom_stands_for_that_geom_only():
    model = mujoco.MjModel.from_xml_string("""
<mujoco><worldbody>
  <body name="left"><freejoint/>
    <geom name="l1" size="0.1" contype="1" conaffinity="0"/>
    <geom name="l2" pos="0 0 0.3" size="0.1" contype="4" conaffinity="4"/></body>
  <body name="right" pos="1 0 0"><freejoint/>
    <geom name="r1" size="0.1" contype="0" conaffinity="1"/>
    <geom name="r2" pos="0 0 0.3" size="0.1" contype="2" conaffinity="2"/></body>
</worldbody></mujoco>""")
    per_geom = fit_model(model, per="geom")
    assert_same_as_mujoco(model, per_geom)
    assert {(per_geom.geoms[i], per_geom.geoms[j]) for i, j in default_pairs(model, per_geom,
                                                                             drop_overlapping_at_qpos0=False)} \
        == {("l1", "r1")}
    per_body = fit_model(model)
    assert _body_pairs(model, per_body, default_pairs(model, per_body, drop_overlapping_at_qpos0=False)) \
        == {("left", "right")}


def test_bounding_geoms_stand_for_their_body():
    # geom_ellipsoids reads back mjccd fit's visual-only bounds: each stands for its body's geoms
    model = mujoco.MjModel.from_xml_string(RULES.format(flags="", contact="").replace(
        '<geom name="a" size="0.1"/>', '<geom name="a" size="0.1"/><geom name="a_bound" type="ellipsoid" '
        'size="0.2 0.2 0.2" contype="0" conaffinity="0" group="5"/>').replace(
        '<geom name="c" size="0.1"/>', '<geom name="c" size="0.1"/><geom name="c_bound" type="ellipsoid" '
        'size="0.2 0.2 0.2" contype="0" conaffinity="0" group="5"/>'))
    ellipsoids = geom_ellipsoids(model)
    assert ellipsoids.geoms == ("a_bound", "c_bound")
    assert [g.tolist() for g in bounded_geoms(model, ellipsoids)] == [[2, 3], [5, 6]]
    assert _default_body_pairs(model, ellipsoids) == {("a", "c")}


# ---------------------------------------------------------------- planes and what mjccd cannot check yet

TERRAIN = """
<mujoco>
  <asset><hfield name="bumps" nrow="3" ncol="3" size="2 2 0.2 0.1"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <geom name="terrain" type="hfield" hfield="bumps" pos="0 0 -0.5"/>
    <geom name="wall" type="plane" size="1 1 0.1" pos="3 0 0" zaxis="-1 0 0" contype="2" conaffinity="2"/>
    <body name="crate"><geom name="crate" type="box" size="0.2 0.2 0.2"/></body>
    <body name="ball" pos="0 0 1"><freejoint/><geom name="ball" size="0.1"/></body>
    <body name="cart" pos="0 0 2"><joint type="slide"/><geom name="cart" size="0.1" contype="2" conaffinity="2"/>
    </body>
    <body name="paddle" mocap="true" pos="0 0 3"><geom name="tray" type="plane" size="0.3 0.3 0.1"/></body>
  </worldbody>
</mujoco>
"""


def test_plane_pairs_and_the_geoms_mjccd_cannot_check_yet():
    model = mujoco.MjModel.from_xml_string(TERRAIN)
    ellipsoids = fit_model(model, tolerance=None)  # one per body
    assert ellipsoids.bodies == ("crate", "ball", "cart")
    assert_same_as_mujoco(model, ellipsoids)
    floor, wall = 0, 2
    # the crate is welded to the world: no static plane meets it; the cart meets the wall by contype 2
    assert {(ellipsoids.bodies[i], int(g)) for i, g in plane_pairs(model, ellipsoids)} == {("ball", floor),
                                                                                            ("cart", wall)}
    found = {u.name: u for u in uncovered_geoms(model, ellipsoids)}
    assert set(found) == {"terrain", "tray"}
    assert (found["terrain"].kind, found["terrain"].ellipsoids) == ("hfield", (1,))
    assert found["terrain"].message == ("geom 'terrain' (hfield): height fields are not checked by mjccd yet; "
                                        "MuJoCo collides it with 'ball'")
    # MuJoCo allows planes on static bodies only, mocap bodies included: one that moves, the crate cannot meet
    assert (found["tray"].kind, found["tray"].ellipsoids) == ("plane", (1,))
    assert found["tray"].message == ("geom 'tray' (plane): planes that move with a mocap body ('paddle') are not "
                                     "checked by mjccd yet, planes welded to the world are; MuJoCo collides it "
                                     "with 'ball'")
    with pytest.warns(CoverageWarning) as said:
        assert warn_uncovered(model, ellipsoids) == tuple(found.values())
    assert [str(w.message) for w in said] == [u.message for u in found.values()]
    assert said[0].filename == __file__  # pointed at the caller


@pytest.mark.dm_control
def test_a_suite_height_field_is_named():
    model = _suite_model("quadruped", "escape")
    (terrain,) = uncovered_geoms(model, fit_model(model))
    assert terrain.message.startswith("geom 'terrain' (hfield): height fields are not checked by mjccd yet; "
                                      "MuJoCo collides it with 'torso', ")


# ---------------------------------------------------------------- self pairs and the named rules

ONE_CHARACTER = """
<mujoco><worldbody>
  <body name="base"><geom size="0.1"/>
    <body name="a" pos="0.3 0 0"><joint type="hinge"/><geom size="0.1"/>
      <body name="b" pos="0.3 0 0"><joint type="hinge"/><geom size="0.1"/>
        <body name="c" pos="0.3 0 0"><joint type="hinge"/><geom size="0.1"/>
          <body name="c_tip" pos="0.2 0 0"><geom size="0.05"/></body>
          <body name="d" pos="0.3 0 0"><joint type="hinge"/><geom size="0.1"/></body>
        </body>
      </body>
    </body>
  </body>
</worldbody></mujoco>
"""
CHAIN = ONE_CHARACTER.replace("</worldbody>", """  <body name="other" pos="0 3 0"><freejoint/><geom size="0.1"/>
    <body name="other_arm" pos="0.3 0 0"><joint type="hinge"/><geom size="0.1"/></body></body>
</worldbody>""")


def test_self_pairs_leave_out_adjacent_bodies():
    model = mujoco.MjModel.from_xml_string(CHAIN)
    ellipsoids = fit_model(model)
    got = _body_pairs(model, ellipsoids, self_pairs(model, ellipsoids))
    # c_tip is welded to c: one rigid body, whose parent is b and child d
    assert got == {("b", "base"), ("base", "c"), ("base", "c_tip"), ("base", "d"), ("a", "c"), ("a", "c_tip"),
                   ("a", "d"), ("b", "d")}
    assert np.array_equal(select_pairs(model, ellipsoids, "self"), self_pairs(model, ellipsoids))
    with pytest.raises(InputError, match=r"^pairs: expected None, 'characters', 'self' or a list of \(body, body\) "
                                         r"pairs, got 'selfs'$"):
        select_pairs(model, ellipsoids, "selfs")


def test_empty_selections_warn_and_say_why():
    model = mujoco.MjModel.from_xml_string(CHAIN.replace('<geom size="0.1"/>', '<geom size="0.1" contype="0"/>')
                                           .replace('<geom size="0.05"/>', '<geom size="0.05" contype="0"/>'))
    ellipsoids = fit_model(model, include_visual=True)
    with pytest.warns(CoverageWarning) as said:
        assert len(select_pairs(model, ellipsoids, None)) == 0
    assert [str(w.message) for w in said] == [
        "no pair to check: every body pair is filtered by contype/conaffinity; pass pairs='characters', "
        "pairs='self' or a list of (body, body) pairs to check others"]
    one = fit_model(model, bodies=["base", "a", "b", "c"], include_visual=True)
    with pytest.warns(CoverageWarning, match=r"^no pair to check: every ellipsoid is under one top-level body "
                                             r"\('base'\); use pairs='self' for self-collision$"):
        assert len(select_pairs(model, one, "characters")) == 0
    chain = fit_model(model, bodies=["b", "c", "c_tip"], include_visual=True)
    with pytest.warns(CoverageWarning, match=r"^no pair to check: no two ellipsoids under one top-level body are on "
                                             r"bodies that are neither one rigid body nor a parent and a child$"):
        assert len(select_pairs(model, chain, "self")) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", CoverageWarning)  # a selection with pairs says nothing
        assert len(select_pairs(model, ellipsoids, "characters")) > 0


def test_overlapping_pairs_dropped_at_qpos0_are_explained():
    model = mujoco.MjModel.from_xml_string("""
<mujoco><worldbody>
  <body name="p"><freejoint/><geom size="0.2"/></body>
  <body name="q" pos="0.3 0 0"><freejoint/><geom size="0.2"/></body>
</worldbody></mujoco>""")
    with pytest.warns(CoverageWarning, match=r"^no pair to check: the one pair MuJoCo would collide already touches "
                                             r"or overlaps in the reference pose qpos0 \(drop_overlapping_at_qpos0\)"):
        assert len(select_pairs(model, fit_model(model), None)) == 0


# ---------------------------------------------------------------- no pair: a monitor, a wrapper cost nothing

LONELY = """
<mujoco><option gravity="0 0 0"/><worldbody>
  <body name="ball"><freejoint/><geom size="0.1" contype="0" conaffinity="0"/></body>
  <body name="box" pos="1 0 0"><freejoint/><geom type="box" size="0.1 0.1 0.1" contype="0" conaffinity="0"/></body>
</worldbody></mujoco>
"""


def test_a_monitor_without_pairs_warns_once_then_only_steps(monkeypatch):
    model = mujoco.MjModel.from_xml_string(LONELY)
    data = mujoco.MjData(model)
    with pytest.warns(CoverageWarning) as said:
        monitor = CCDMonitor(model, data, fit_model(model, include_visual=True))
    assert len(said) == 1 and "filtered by contype/conaffinity" in str(said[0].message)

    def no_copies(*args):
        raise AssertionError("a monitor without pairs copied a state")

    monkeypatch.setattr(monitor_module, "capture", no_copies)
    assert monitor.mode == "geoms" and monitor.adapter is None
    monkeypatch.setattr(monitor.geoms, "check", no_copies)
    monkeypatch.setattr(monitor.geoms, "check_poses", no_copies)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        data.qvel[0] = 1.0
        assert monitor.step(3) is None
    assert data.qpos[0] == pytest.approx(3 * model.opt.timestep)
    report = monitor.last_report
    assert (report.pairs_checked, report.unstable, report.contacts) == (0, False, ())
    data.qfrc_applied[0] = np.nan  # MuJoCo's bad-state test still runs
    assert monitor.step() is None and monitor.last_report.unstable


@pytest.mark.dm_control
def test_a_dm_control_wrapper_without_pairs_adds_the_no_contact_entries():
    from dm_control import suite

    from mjccd.dm_control import OBSERVATION_KEYS, CCDWrapper

    # geoms mode: MuJoCo collides the rails with the cart and the pole; their one-per-body ellipsoids overlap at
    # qpos0, so ellipsoid mode with that fit drops those pairs and has none left
    env = CCDWrapper(suite.load("cartpole", "swingup", task_kwargs={"random": 0}), planes=False)
    rows = env.monitor.geoms.labels_of_rows
    assert sorted((rows[a], rows[b]) for a, b in env.monitor.pairs) == [
        ("rail1", "cart"), ("rail1", "pole_1"), ("rail2", "cart"), ("rail2", "pole_1")]
    with pytest.warns(CoverageWarning, match="^no pair to check: ") as said:
        cartpole = suite.load("cartpole", "swingup", task_kwargs={"random": 0})
        env = CCDWrapper(cartpole, planes=False, mode="ellipsoids",
                         ellipsoids=fit_model(cartpole.physics.model.ptr, tolerance=None))
    assert len(said) == 1 and len(env.monitor.pairs) == 0
    spec = env.observation_spec()
    env.reset()
    with warnings.catch_warnings():
        warnings.simplefilter("error", CoverageWarning)
        for _ in range(3):
            ts = env.step(np.zeros(1))
    for key in OBSERVATION_KEYS:
        spec[key].validate(ts.observation[key])
    assert np.isinf(ts.observation["ccd/contact_time"]) and tuple(ts.observation["ccd/contact_pair"]) == (-1, -1)
    assert "position" in ts.observation and (env.last_contacts, env.last_reports) == ([], [])


# ---------------------------------------------------------------- replay of one character


def test_replay_of_one_character_checks_its_self_pairs(tmp_path):
    from mjccd import replay

    model_path = tmp_path / "skeleton.xml"
    model_path.write_text(ONE_CHARACTER.replace('<geom size="0.1"/>', '<geom type="ellipsoid" size="0.1 0.1 0.1"/>')
                          .replace('<geom size="0.05"/>', '<geom type="ellipsoid" size="0.05 0.05 0.05"/>'))
    model = mujoco.MjModel.from_xml_path(str(model_path))
    with pytest.warns(CoverageWarning, match=r": one character \('base'\): checking its self-collisions, 8 pairs of "
                                             r"ellipsoids on bodies neither rigidly joined nor parent and child "
                                             r"\(--pairs self\)$"):
        ellipsoids, pairs = replay.replay_ellipsoids(model, source=str(model_path))
    assert np.array_equal(pairs, self_pairs(model, ellipsoids))
    with pytest.raises(replay.ReplayError, match=r"use pairs='self' for self-collision$"):
        replay.replay_ellipsoids(model, "characters", source=str(model_path))
    with pytest.raises(replay.ReplayError, match=r"^pairs: expected one of characters, self"):
        replay.replay_ellipsoids(model, "everything", source=str(model_path))


@pytest.mark.slow
def test_replay_of_an_imported_skeleton_checks_its_self_collisions(tmp_path, capsys):
    clip = ROOT / "data" / "mocap" / "cmu_14_03_boxing_first10s.bvh"
    model, fitted, traj, short = (tmp_path / n for n in ("sk.xml", "sk_fit.xml", "sk.npz", "short.npz"))
    assert cli.main(["import-bvh", str(clip), "-o", str(model), "--traj", str(traj)]) == 0
    assert cli.main(["fit", str(model), "-o", str(fitted), "--include-visual", "-q"]) == 0
    with np.load(traj) as d:
        np.savez(short, qpos=d["qpos"][:24], time=d["time"][:24])
    capsys.readouterr()
    assert cli.main(["replay", str(fitted), str(short), "--no-render", "--rows", "3"]) == 0
    out, err = capsys.readouterr()
    notes = [line for line in err.splitlines() if line.startswith("mjccd replay:")]
    assert len(notes) == 1
    found = re.fullmatch(rf"mjccd replay: {re.escape(str(fitted))}: one character \('Hips'\): checking its "
                         r"self-collisions, (\d+) pairs of ellipsoids on bodies neither rigidly joined nor parent "
                         r"and child \(--pairs self\)", notes[0])
    assert found and int(found[1]) > 100
    assert re.search(r"24 frames \(23 intervals\), \d+ geoms, \d+ pairs", out)
    assert cli.main(["replay", str(fitted), str(short), "--no-render", "--pairs", "characters"]) == 2
    assert "use pairs='self' for self-collision" in capsys.readouterr().err


def test_a_gymnasium_wrapper_without_pairs_adds_the_no_contact_entries():
    gymnasium = pytest.importorskip("gymnasium")
    from mjccd.mujoco.gym import CCDGymWrapper

    try:
        env = gymnasium.make("InvertedPendulum-v5")
    except Exception as exc:  # gymnasium without its MuJoCo environments
        pytest.skip(f"InvertedPendulum-v5: {exc}")
    with pytest.warns(CoverageWarning, match="^no pair to check: "):
        wrapped = CCDGymWrapper(env, planes=False)
    wrapped.reset(seed=0)
    info = wrapped.step(np.zeros(1))[4]["ccd"]
    assert np.isinf(info["contact_time"]) and tuple(info["contact_pair"]) == (-1, -1)
    assert (info["contacts"], info["reports"], info["unstable"]) == ([], [], False)
    assert (wrapped.last_contacts, wrapped.last_reports) == ([], [])


CLOSE_RODS = """
<mujoco>
  <option gravity="0 0 0"/>
  <worldbody>
    <body name="rod_a" pos="0 0 1"><freejoint/><geom type="capsule" fromto="-0.5 0 0 0.5 0 0" size="0.02"/></body>
    <body name="rod_b" pos="0 0.045 1"><freejoint/><geom type="capsule" fromto="-0.5 0 0 0.5 0 0" size="0.02"/></body>
    <body name="ball" pos="0 1 1"><freejoint/><geom type="sphere" size="0.05"/></body>
  </worldbody>
</mujoco>
"""


def test_no_pair_mujoco_collides_is_left_out_without_a_warning():
    """Two rods 5 mm apart whose one-per-body ellipsoids overlap in qpos0: ellipsoid mode leaves their pair out
    and says so (naming it); every body pair in MuJoCo's data.contact as the rods are pushed together is
    either checked or named in that warning; geoms mode checks it."""
    import warnings

    from mjccd.mujoco import CCDMonitor, fit_model
    from mjccd.mujoco.warnings import CoverageWarning

    model = mujoco.MjModel.from_xml_string(CLOSE_RODS)
    data = mujoco.MjData(model)
    ellipsoids = fit_model(model)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        monitor = CCDMonitor(model, data, ellipsoids, mode="ellipsoids")
    said = " ".join(str(w.message) for w in caught if issubclass(w.category, CoverageWarning))
    assert "rod_a-rod_b" in said
    checked = {tuple(sorted(monitor.labels[b] for b in pair)) for pair in
               (ellipsoids.body_ids(model)[list(p)] for p in monitor.pairs)}
    data.qvel[6:9] = [0.0, -0.5, 0.0]  # rod_b towards rod_a
    touched = set()
    for _ in range(200):
        mujoco.mj_step(model, data)
        for k in range(data.ncon):
            b1, b2 = model.geom_bodyid[data.contact[k].geom1], model.geom_bodyid[data.contact[k].geom2]
            touched.add(tuple(sorted((monitor.labels[b1], monitor.labels[b2]))))
    assert ("rod_a", "rod_b") in touched
    for a, b in touched:
        assert (a, b) in checked or f"{a}-{b}" in said, (a, b)
    geoms = CCDMonitor(model, mujoco.MjData(model), ellipsoids)
    assert any({geoms.labels[geoms.geoms.body[i]], geoms.labels[geoms.geoms.body[j]]} == {"rod_a", "rod_b"}
               for i, j in geoms.pairs)
