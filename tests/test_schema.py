"""One declaration per parameter: the parameter dataclasses are the schema of their sections
(aac_sumo.config.schema): the planner's and the coordinators' (``@section``), each experiment
kind's own and the further sections a kind reads (``register_experiment(params=..., sections=...)``).
Every key of a dataclass-backed section has its field, with the same default; every key a bundled
scenario sets has one; every field has a doc; a scenario builds each dataclass by the generic
from_section; config/keys.py writes no key table for them."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import runpy
import tomllib

import pytest

from aac_sumo import config, registry
from aac_sumo.config import ScenarioError, schema
from aac_sumo.coordination.aac import AacParams
from aac_sumo.coordination.lfc import LfcParams
from aac_sumo.experiments import common
from aac_sumo.mpc.problem import N_WEIGHTS, WEIGHTS
from aac_sumo.mpc.settings import MpcConfig

config.common()  # the providers loaded, then their sections
#: Every dataclass-backed section: ``{section: [dataclass, ...]}``.
SECTIONS = dict(schema.SECTIONS) | {name: [cls] for name, cls in registry.SECTION_PARAMS.items()}
#: Keys of those sections that no dataclass declares: a registry choice, not a parameter.
NOT_PARAMETERS = {("controller", "coordinator")}
#: Sections that stay key tables in config/keys.py: the config's own.
KEY_TABLES = {"scenario"}
BUNDLED = sorted(config.BUNDLED_DIR.glob("*.toml"))


def loaded(section: str) -> dict[str, config.Key]:
    """The key table of ``section`` as the loaded config holds it (what ``aac-sumo keys`` lists)."""
    tables = [config.COMMON, config.KIND_SECTIONS, *config.KIND_EXTRA_SECTIONS.values()]
    return next(t[section] for t in tables if section in t)


def declared_fields(section):
    """``{key: (field, Param, dataclass)}`` of every field that declares a key of ``section``."""
    out = {}
    for cls in SECTIONS[section]:
        for f, p in schema.scenario_fields(cls):
            out.setdefault(schema.key_name(f), []).append((f, p, cls))
    return out


def test_the_dataclass_sections_are_the_ones_expected():
    assert set(SECTIONS) == {"controller", "robot", "aac", "lfc", "metrics", "orca", "cbf_qp", "sumo", *registry.kinds()}


def test_every_section_but_the_key_tables_is_declared_by_dataclasses():
    every = {section for kind in registry.kinds() for section in config.schema_for(kind)}
    assert every - set(SECTIONS) == KEY_TABLES


@pytest.mark.parametrize("section", sorted(SECTIONS))
def test_every_key_of_a_dataclass_section_has_its_field_with_the_same_default(section):
    fields = declared_fields(section)
    for key, declared in loaded(section).items():
        if (section, key) in NOT_PARAMETERS:
            continue
        assert key in fields, f"{section}.{key} has no dataclass field"
        for f, p, cls in fields[key]:
            assert schema.key_default(f, p) == declared.default, f"{cls.__name__}.{f.name}: {schema.key_default(f, p)!r} != {declared.default!r}"
            if p.parse is not None:
                assert p.parse(declared.default) == f.default, f"{cls.__name__}.{f.name}"
    assert set(fields) <= set(loaded(section)), "a field declares a key the section lacks"


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.stem)
def test_every_key_a_bundled_scenario_sets_has_its_dataclass_field(path):
    for section, table in tomllib.loads(path.read_text()).items():
        if section in KEY_TABLES:
            continue
        assert section in SECTIONS, f"{path.name}: [{section}] has no dataclass"
        fields = declared_fields(section)
        for key in table:
            assert (section, key) in NOT_PARAMETERS or key in fields, f"{path.name}: {section}.{key} has no dataclass field"


def test_no_key_table_is_hand_written_for_a_dataclass_section():
    """config/keys.py, run afresh (the loaded tables have the derived sections filled in), holds
    no key of a dataclass-backed section but the registry's choice."""
    path = importlib.util.find_spec("aac_sumo.config.keys").origin
    fresh = runpy.run_path(path)
    tables = [fresh["COMMON"], fresh["KIND_SECTIONS"], *fresh["KIND_EXTRA_SECTIONS"].values()]
    for section in SECTIONS:
        for table in tables:
            assert {(section, key) for key in table.get(section, {})} <= NOT_PARAMETERS, section
    written = len(re.findall(r"\bKey\(", open(path).read()))  # the source itself: no Key( beyond the key tables'
    assert written == sum(len(fresh["COMMON"][section]) for section in KEY_TABLES) + len(NOT_PARAMETERS)


@pytest.mark.parametrize("section", ["robot", "metrics", "sumo", *registry.kinds()])
def test_a_scenario_of_defaults_builds_its_dataclass_defaults(section):
    kind = next(k for k in registry.kinds() if section in config.schema_for(k))
    scenario = config.Scenario.from_dict({"scenario": {"kind": kind}})
    (cls,) = SECTIONS[section]
    assert schema.from_section(cls, scenario, section) == cls()


def test_a_set_list_key_reaches_its_field_as_a_tuple():
    scenario = config.load("lane_change", ["lane_change.exit_lanes=[1, 2]", "sumo.outputs=fcd,summary"])
    assert schema.from_section(registry.SECTION_PARAMS["lane_change"], scenario, "lane_change").exit_lanes == (1, 2)
    assert schema.from_section(registry.SECTION_PARAMS["sumo"], scenario, "sumo").outputs == ("fcd", "summary")


def test_fields_read_from_another_section_have_its_default():
    for classes in SECTIONS.values():
        for cls in classes:
            for f in dataclasses.fields(cls):
                p = schema.meta(f)
                if "." in (p.key or ""):
                    section, key = p.key.split(".")
                    assert config.common()[section][key].default == f.default, f"{cls.__name__}.{f.name}"


def every_dataclass():
    seen = []
    stack = [cls for classes in SECTIONS.values() for cls in classes]
    while stack:
        cls = stack.pop()
        if cls not in seen:
            seen.append(cls)
            stack += [type(f.default) for f in dataclasses.fields(cls) if schema.meta(f).nested]
    return seen


def test_every_field_is_declared_with_a_doc():
    for cls in every_dataclass():
        for f in dataclasses.fields(cls):
            assert schema.meta(f).doc.strip(), f"{cls.__name__}.{f.name} has no doc"


def test_a_shared_key_has_one_default_in_every_dataclass_that_reads_it():
    for section in SECTIONS:
        for key, declared in declared_fields(section).items():
            assert len({repr(schema.key_default(f, p)) for f, p, _ in declared}) == 1, f"{section}.{key}"
            assert sum(not p.shared for _, p, _ in declared) == 1, f"{section}.{key} is declared (not shared) once"


def test_defaults_build_the_dataclasses_defaults():
    """A scenario of defaults builds every dataclass equal to its own defaults (seed and dt aside)."""
    scenario = config.Scenario.from_dict({"scenario": {"kind": "braking"}, "controller": {"anticipate": True}})
    assert common.mpc_config(scenario) == MpcConfig(dt=scenario["scenario.dt"])
    from aac_sumo.coordination.aac import AacParams
    from aac_sumo.coordination.anticipation import Anticipation
    from aac_sumo.coordination.cbf_qp import CbfQpParams
    from aac_sumo.coordination.lfc import LfcParams
    from aac_sumo.coordination.orca import OrcaParams
    assert common.aac_params(scenario) == AacParams()
    assert common.anticipation(scenario) == Anticipation(enabled=True)
    assert schema.from_section(LfcParams, scenario, "lfc") == LfcParams()
    assert schema.from_section(OrcaParams, scenario, "orca") == OrcaParams()
    assert schema.from_section(CbfQpParams, scenario, "cbf_qp") == CbfQpParams()


def test_a_set_key_reaches_its_field_and_nested_fields():
    scenario = config.load("braking", ["controller.sigmoid_k=3.5", "controller.obstacle_slots=5", "aac.tree_step=0.7",
                                       "aac.authorities=\"clusters\"", "scenario.seed=7"])
    mpc, aac = common.mpc_config(scenario), common.aac_params(scenario)
    assert mpc.fcbf.k == 3.5 and mpc.slots == 5
    assert aac.proximity.step == 0.7 and aac.authorities.per_cluster and aac.seed == 7


@pytest.mark.parametrize("sets, key, text", [
    (["aac.fallback=tracking"], "aac.fallback", "expected brake unless aac.safety_stop is true, got 'tracking'"),
    (["lfc.ignore_followers=true"], "lfc.ignore_followers", "expected false unless lfc.safety_stop is true, got True"),
    (["aac.commit=false", "aac.detour=true"], "aac.detour", "expected false unless aac.commit is true, got True"),
    (["aac.commit=false", "aac.manoeuvre=true"], "aac.manoeuvre", "expected false unless aac.commit is true, got True"),
])
def test_the_safety_rules_name_the_scenario_key(sets, key, text):
    scenario = config.load("swarm_rescue", sets)
    section = key.split(".")[0]
    with pytest.raises(ScenarioError) as err:
        schema.from_section({"aac": AacParams, "lfc": LfcParams}[section], scenario, section)
    assert err.value.key == key and str(err.value).endswith(f"{key}: {text}")


def test_the_weight_vector_is_filled_by_name():
    w = MpcConfig(q_pos=2.0, q_heading=3.0, q_speed=4.0, r_accel=5.0, r_steer=6.0, s_accel=7.0, s_steer=8.0, terminal_scale=10.0).weights()
    assert len(w) == N_WEIGHTS
    assert w[WEIGHTS["q"]].tolist() == [2.0, 2.0, 3.0, 4.0] and w[WEIGHTS["p"]].tolist() == [20.0, 20.0, 30.0, 40.0]
    assert w[WEIGHTS["r"]].tolist() == [5.0, 6.0] and w[WEIGHTS["s"]].tolist() == [7.0, 8.0]


def test_a_negative_zero_is_read_as_zero_so_a_jitter_of_it_builds():
    """``-0.0`` passes ``>= 0`` but numpy's ``uniform(-x, x)`` refuses it as a width (the fuzz
    test found ``braking.t_brake_jitter = -0.0``): a number key reads it as 0.0."""
    import math

    from aac_sumo import experiments

    scenario = config.load(config.resolve("braking")).with_overrides(["braking.t_brake_jitter=-0.0"])
    assert math.copysign(1.0, scenario["braking.t_brake_jitter"]) == 1.0
    experiments.build(scenario)
