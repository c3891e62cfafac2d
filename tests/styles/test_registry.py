"""The wall style registry (wallbatch.styles.STYLES): one entry per style, and everything derived
from it. Every test here is parametrised over the registry, so a new style is tested by being
registered.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest

from wallbatch.config import fixline
from wallbatch.config.models import REGION_POTENTIALS, WALL_MODELS, RegionWall, config_from_dict
from wallbatch.config.source import WALL_TAGS, ConfigError
from wallbatch.engine.engine import Engine
from wallbatch.lammps.export import DECISIONS, WALL_WRITERS
from wallbatch.scene.build import build_case
from wallbatch.scene.case import Case, structure_key
from wallbatch.styles import STYLES, WallStyle
from wallbatch.styles.base import MAX_COMPILED_PARAMS, _missing

SRC = Path(__file__).resolve().parents[2] / "src"

NAMES = sorted(STYLES)
CLOSED = sorted(n for n, s in STYLES.items() if s.force is not _missing)  # E(r), F(r) in closed form


# ----------------------------------------------------------------------------- generic test values


_EXAMPLES = tempfile.mkdtemp(prefix="wallbatch-registry-")  # files of the per-face styles' examples


def wall_values(style: WallStyle) -> dict:
    """The wall keys of a style's example (wall/table: tabstyle, N); {} for most styles."""
    return style.example(_EXAMPLES)[0] if style.per_face else {}


def values(style: WallStyle) -> dict[str, float]:
    """Parameter values for a style, from the unit kinds alone (so a new style needs no table):
    energies 1.3, distances 0.9, cut-off 2.5, other kinds 2.0; a radius 0.5 when needed. A style
    built per face (an expression, a table file) gives its own example face."""
    if style.per_face:
        return dict(style.example(_EXAMPLES)[1])
    p = {}
    for prm in style.parameters:
        if prm.name == "cutoff":
            p[prm.name] = 2.5
        else:
            p[prm.name] = {"energy": 1.3, "distance": 0.9}.get(prm.unit, 2.0)
    if style.needs_radius:
        p["radius"] = 0.5
    return p


def contact(style: WallStyle, p: dict[str, float]) -> float:
    """A distance close to the wall: the radius plus a tenth of the smallest length parameter."""
    lengths = [p[q.name] for q in style.parameters if q.unit == "distance" and q.name != "cutoff"] or [1.0]
    return p.get("radius", 0.0) + 0.1 * min(lengths)


def distances(style: WallStyle, p: dict[str, float], n: int = 9) -> np.ndarray:
    lo = contact(style, p)
    return np.linspace(lo, p["cutoff"], n + 2)[1:-1]


# ----------------------------------------------------------------------------- one source per style


@pytest.mark.parametrize("name", NAMES)
def test_style_name_is_a_literal_in_exactly_one_source_file(name):
    """`grep -rl '"NAME"' src/`: only the style's own entry module spells its name."""
    files = sorted(str(p.relative_to(SRC)) for p in SRC.rglob("*.py")
                   if re.search(rf"""["']{re.escape(name)}["']""", p.read_text()))
    assert len(files) == 1, f"{name!r} is written in {files}: derive it from the registry instead"
    assert files[0].startswith("wallbatch/styles/"), files


@pytest.mark.parametrize("name", NAMES)
def test_entry_is_complete(name):
    style = STYLES[name]
    assert style.name == name and style.lammps == f"wall/{name}"
    assert style.params[-1] == "cutoff" and style.param("cutoff").positive and not style.param("cutoff").variable
    assert style.positional == ("coord", *style.params)
    assert len(set(style.params)) == len(style.params)
    for prm in style.parameters:
        assert (prm.unit or not prm.numeric) and (prm.doc or prm.name == "cutoff"), prm
    if style.compiled:
        assert style.force is not _missing and len(style.args_names) <= MAX_COMPILED_PARAMS
    if style.shifted and not style.per_face:
        assert style.energy is not _missing
    if style.per_face:  # its example face passes its checks and builds a style with a force
        wall, face = style.example(_EXAMPLES)
        assert style.check_face({"coord": 0.0, **face}, wall, _EXAMPLES) == []
        face_style, params, _ = style.face_style({"coord": 0.0, **face}, wall, _EXAMPLES)
        assert params["cutoff"] == face["cutoff"] and not face_style.per_face
        assert np.isfinite(face_style.force(1.0, *face_style.args(params)))


# ----------------------------------------------------------------------------- physics invariants


@pytest.mark.parametrize("name", CLOSED)
def test_force_is_minus_gradient(name):
    style = STYLES[name]
    p = values(style)
    r = distances(style, p)
    h = 1e-6 * r
    numeric = -(style.energy_force(r + h, p)[0] - style.energy_force(r - h, p)[0]) / (2.0 * h)
    force = style.energy_force(r, p)[1]
    np.testing.assert_allclose(force, numeric, rtol=2e-6, atol=1e-8 * np.abs(force).max())


@pytest.mark.parametrize("name", CLOSED)
def test_scalar_and_array_agree(name):
    """Plain arithmetic: the same numbers for floats and for arrays, element by element."""
    style = STYLES[name]
    p = values(style)
    r = distances(style, p)
    e, f = style.energy_force(r, p)
    for i, ri in enumerate(r):
        e1, f1 = style.energy_force(float(ri), p)
        assert float(e1) == e[i] and float(f1) == f[i]


@pytest.mark.parametrize("name", [n for n in CLOSED if STYLES[n].shifted])
def test_shifted_energy(name):
    """E(rc) - E(rc) is exactly 0; elsewhere the shifted energy is E(r) - E(rc) to rounding."""
    style = STYLES[name]
    p = values(style)
    assert float(style.shifted_energy(p["cutoff"], p)) == 0.0
    r = distances(style, p)
    e, _ = style.energy_force(r, p)
    e_rc, _ = style.energy_force(p["cutoff"], p)
    plain = e - e_rc
    shifted = style.shifted_energy(r, p)
    np.testing.assert_allclose(shifted, plain, rtol=0, atol=1e-13 * (np.abs(e) + abs(e_rc)).max())


@pytest.mark.parametrize("name", CLOSED)
def test_repulsive_near_the_wall(name):
    style = STYLES[name]
    p = values(style)
    r = contact(style, p)
    assert style.energy_force(r, p)[1] > 0
    assert style.shifted_energy(r, p) > 0


def _uses_libm(style: WallStyle) -> bool:
    """A force calling a transcendental function may differ by a few ulp between numba and NumPy
    (two libms); plain arithmetic must agree bit for bit."""
    return bool(re.search(r"np\.(exp|expm1|log|log1p|sqrt|arctanh|sin|cos|power)\b", inspect.getsource(style.force)))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(n for n, s in STYLES.items() if s.compiled))
def test_compiled_force_is_the_numpy_force(name):
    fast = pytest.importorskip("wallbatch.engine.compiled")
    if fast.njit is None:
        pytest.skip("numba not importable")
    style = STYLES[name]
    p = values(style)
    r = np.linspace(contact(style, p), 1.2 * p["cutoff"], 401)
    args = style.args(p)
    want = style.force(r, *args)
    got = np.array([fast.FORCES[fast.STYLE_IDS[name]](float(ri), *[float(a) for a in args]) for ri in r])
    assert fast.COMPILED_STYLES[fast.STYLE_IDS[name]] is style
    if _uses_libm(style):  # each libm call may round differently: a few ulp (morse: exp * expm1, <= 3)
        ulps = np.abs(got.view(np.int64) - want.view(np.int64))
        assert ulps.max() <= 4
    else:
        assert np.array_equal(got, want)


def _scene(style: WallStyle, zs: list[float]) -> dict:
    """Atoms at heights zs above a zlo wall of `style` at z = 0 (and nothing else)."""
    p = values(style)
    group = {"group": "a", "create": {"positions": [[2.0, 2.0, z] for z in zs]}, "mass": 1.0}
    if style.needs_radius:
        group["radius"] = p["radius"]
    if style.needs_shape:
        group["shape"] = [0.3, 0.3, 0.3]
        group["orientation"] = [1.0, 0.0, 0.0, 0.0]
    face = {"coord": 0.0, **{k: v for k, v in p.items() if k != "radius"}}
    return {"box": {"lo": [0, 0, 0], "hi": [4, 4, 8], "boundary": ["p", "p", "f"]}, "atoms": [group],
            "walls": {"w": {"style": style.name, "units": "box", "energy": True, **wall_values(style),
                            "zlo": face}},
            "timestep": 0.001, "run": {"steps": 0}}


@pytest.mark.parametrize("name", NAMES)
def test_no_force_past_the_cutoff(name):
    """The engine masks r >= rc: an atom just past the cut-off feels nothing, one inside feels
    -side F(r) along z (the style's own force where it has a closed form)."""
    style = STYLES[name]
    rc = values(style)["cutoff"]
    inside = 0.6 * rc
    eng = Engine([build_case(config_from_dict(_scene(style, [inside, rc + 1e-9, rc + 0.5])))])
    eng.setup()
    f = eng.state.f[0]
    assert np.all(f[1:] == 0.0)
    assert f[0, 2] != 0.0
    if style.force is not _missing:
        assert f[0, 2] == style.force(inside, *style.args(values(style)))
    if style.per_face:  # the face's own style
        face_style, params, _ = style.face_style({"coord": 0.0, **values(style)}, wall_values(style), _EXAMPLES)
        assert f[0, 2] == face_style.force(inside, *face_style.args(params))


# ----------------------------------------------------------------------------- what derives from an entry


@pytest.mark.parametrize("name", NAMES)
def test_config_model_and_positional_form(name):
    style = STYLES[name]
    model = WALL_MODELS[name]
    assert model._style is style
    face_model = model.model_fields["zlo"].annotation.__args__[0]
    assert tuple(face_model.model_fields) == ("coord", *style.face_keys)
    assert all(p.name in model.model_fields for p in style.wall_parameters)
    p = values(style)
    scene = _scene(style, [1.5])
    by_name = config_from_dict(scene).walls["w"].zlo
    scene["walls"]["w"]["zlo"] = [0.0, *[p[k] for k in style.params]]
    positional = config_from_dict(scene).walls["w"].zlo
    assert by_name == positional


@pytest.mark.parametrize("name", NAMES)
def test_fix_line_round_trip(name):
    style = STYLES[name]
    p = values(style)

    def word(k: str) -> str:
        prm = style.param(k)
        return repr(float(p[k])) if prm.numeric else f'"{p[k]}"' if prm.quoted else str(p[k])

    words = " ".join(word(k) for k in style.params)
    head = "".join(f"{v} " for v in wall_values(style).values())
    line = f"fix w all {style.lammps} {head}zlo EDGE {words} zhi 5.0 {words} units box"
    parsed = fixline.parse_fix_line(line, "w")
    assert parsed["style"] == name and parsed["zlo"] == {"coord": "EDGE", **{k: p[k] for k in style.params}}
    assert all(parsed[k] == v for k, v in wall_values(style).items())
    assert fixline.to_fix_line("w", parsed) == line
    assert f"wall/{name}" in fixline.SUPPORTED_STYLES and name in WALL_TAGS and name in WALL_WRITERS
    for prm in (q for q in style.parameters if q.numeric):  # v_name where the entry allows a variable, else refused
        bad = line.replace(f"zhi 5.0 {words}", "zhi 5.0 " + " ".join(
            "v_x" if q == prm.name else word(q) for q in style.params))
        if prm.variable:
            assert fixline.parse_fix_line(bad, "w")["zhi"][prm.name] == "v_x"
        else:
            with pytest.raises(fixline.FixLineError):
                fixline.parse_fix_line(bad, "w")


@pytest.mark.parametrize("name", NAMES)
def test_parameter_checks(name):
    """Required parameters must be given; numbers below a parameter's lower bound are refused."""
    style = STYLES[name]
    for prm in style.parameters:
        scene = _scene(style, [1.5])
        face = scene["walls"]["w"]["zlo"]
        if prm.required:
            del face[prm.name]
            with pytest.raises(ConfigError, match=prm.name):
                config_from_dict(scene)
            face[prm.name] = values(style)[prm.name]
        if prm.min is not None:
            face[prm.name] = prm.min - 0.5
            with pytest.raises(ConfigError, match=rf"{prm.name} must be >= "):
                config_from_dict(scene)
        if prm.positive:
            face[prm.name] = 0.0
            with pytest.raises(ConfigError, match=prm.name):
                config_from_dict(scene)


def test_region_potentials_and_decisions():
    assert REGION_POTENTIALS == tuple(n for n, s in STYLES.items() if s.region)
    assert set(RegionWall.model_fields["potential"].annotation.__args__) == set(REGION_POTENTIALS)
    for n, s in STYLES.items():
        if s.decision:
            assert DECISIONS[n] == s.decision
        for prm in s.parameters:
            if prm.lammps_variable_note:
                assert DECISIONS[f"{n}_{prm.name}"] == prm.lammps_variable_note


# ----------------------------------------------------------------------------- structure_key


def _case(**walls) -> Case:
    d = {"box": {"lo": [0, 0, 0], "hi": [4, 4, 8], "boundary": ["p", "p", "f"]},
         "atoms": [{"group": "a", "create": {"random": {"count": 5}}, "mass": 1.0, "velocity": {"temperature": 1.0}}],
         "walls": walls, "timestep": 0.001, "run": {"steps": 10}}
    return build_case(config_from_dict(d))


def _plain_wall() -> dict:
    """A zlo wall of the first style that needs nothing of the atoms."""
    style = next(s for n, s in sorted(STYLES.items()) if not (s.needs_radius or s.needs_shape))
    return {"style": style.name, "units": "box", "zlo": {"coord": 0.0, **values(style)}}


def test_structure_key_follows_the_declarations():
    """Every Case field is either declared per_case() (stays out of the key) or is in the key;
    numbers differ per case, structure does not."""
    a = _case(w=_plain_wall())
    lj = _plain_wall()
    key = dict(structure_key(a))
    for f in dataclasses.fields(Case):
        if f.metadata.get("per_case"):
            assert f.name not in key
        else:
            assert f.name in key, f"Case.{f.name} is neither per_case() nor in the key"
    # per-case fields: a different value keeps the key
    b = dataclasses.replace(a, x=a.x + 0.1, v=a.v * 2.0, dt=0.002, name="other")
    assert structure_key(b) == structure_key(a)
    # a number in a face may differ, a variable name may not
    p2 = dict(lj, zlo={**lj["zlo"], "coord": 0.5})
    assert structure_key(_case(w=p2)) == structure_key(a)
    assert structure_key(dataclasses.replace(a, steps=11)) != structure_key(a)
    assert structure_key(dataclasses.replace(a, box_hi=a.box_hi + 1.0)) != structure_key(a)


def test_structure_key_is_taken_once_per_case_and_left_out_of_its_pickle(monkeypatch):
    """A sweep's runner asks for a case's key three times: it is computed once per Case object;
    a pickled or copied case (sent to a cluster worker) carries no key and takes the same one
    again; a replaced case takes its own."""
    import copy
    import pickle

    from wallbatch.scene import case as case_module

    a = _case(w=_plain_wall())
    calls = []
    real = case_module._fields_key
    monkeypatch.setattr(case_module, "_fields_key", lambda c: (isinstance(c, Case) and calls.append(c)) or real(c))
    key = structure_key(a)
    assert structure_key(a) is key and structure_key(a) is key and len(calls) == 1
    for other in (pickle.loads(pickle.dumps(a)), copy.deepcopy(a)):
        assert case_module._KEY_MEMO not in vars(other)
        assert structure_key(other) == key
    assert len(calls) == 3
    assert case_module._KEY_MEMO.encode() not in pickle.dumps(a)  # the key stays home
    assert structure_key(dataclasses.replace(a, steps=11)) != key and len(calls) == 4


def test_structure_key_refuses_a_field_it_has_no_rule_for():
    """A new Case field of a type without a key rule fails loudly instead of dropping out of the key."""

    @dataclasses.dataclass(frozen=True)
    class Extended(Case):
        gadget: object = dataclasses.field(default_factory=object)

    a = _case(w=_plain_wall())
    ext = Extended(**{f.name: getattr(a, f.name) for f in dataclasses.fields(Case)})
    with pytest.raises(TypeError, match="no rule for a object"):
        structure_key(ext)


@pytest.mark.parametrize("name", sorted(n for n, s in STYLES.items() if s.compiled))
def test_compiled_engine_runs_every_compiled_style(name, monkeypatch):
    """A registered compiled style runs in the numba path (no fallback) and gives the NumPy
    engine's samples (to 1e-14 of each output's scale, as tests/engine/test_compiled.py)."""
    fast = pytest.importorskip("wallbatch.engine.compiled")
    if fast.njit is None:
        pytest.skip("numba not importable")
    style = STYLES[name]
    p = values(style)
    faces = {f: {"coord": c, **{k: v for k, v in p.items() if k != "radius"}} for f, c in (("zlo", 0.0), ("zhi", 9.0))}
    group = {"group": "a", "create": {"random": {"count": 40, "region": "mid"}}, "mass": 1.0,
             "velocity": {"temperature": 1.0}}
    if style.needs_radius:
        group["radius"] = p["radius"]
    d = {"seed": 3, "box": {"lo": [0, 0, 0], "hi": [5, 5, 9], "boundary": ["p", "p", "f"]}, "atoms": [group],
         "regions": {"mid": {"style": "block", "lo": [0, 0, 1.4], "hi": [5, 5, 7.6], "units": "box"}},
         "walls": {"w": {"style": name, "units": "box", "energy": True, **faces}},
         "timestep": 0.002, "run": {"steps": 200, "thermo": 50}}
    case = build_case(config_from_dict(d))
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref = Engine([case]).run()[0]
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine([case])
    got = eng.run()[0]
    assert eng.fast is not None and eng.fast.compiled_chunks > 0 and eng.fast.fallbacks == 0
    assert ref.status == got.status == "ok"
    assert np.all(ref.data["wall_force"][1:] != 0.0)  # the walls act on atoms at every sample
    for key, want in ref.data.items():
        scale = np.nanmax(np.abs(want)) if np.isfinite(want).any() else 0.0
        np.testing.assert_allclose(got.data[key], want, rtol=0, atol=1e-14 * max(scale, 1e-300), err_msg=key)
