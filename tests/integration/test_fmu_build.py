"""Building the FMUs (papwc.fmubuild): model descriptions completed from the model layer's
tables, reproducible archives, the bundled code, and build errors."""

from __future__ import annotations

import errno
import hashlib
import math
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

import papwc
from papwc.errors import BuildError, OutputError
from papwc.fmubuild.fmus import FMUS, build_fmu, fmu_digest, guid, is_current, recipe
from papwc.fmubuild.model_description import (
    complete_model_description,
    rewrite_fmu,
    xml_number,
)
from papwc.fmubuild.model_description import read_model_description as read_md_xml
from papwc.fmubuild.pythonfmu_build import FmuSource, build_pythonfmu
from papwc.model.plant import PLANT_VARIABLES
from papwc.model.units import UNIT_DEFINITIONS
from papwc.model.variables import Variable

PACKAGE_DIR = Path(papwc.__file__).resolve().parent
FMU_NAMES = [r.name for r in FMUS]
#: (FMU, variable) for every variable of every FMU, from the recipes' tables.
ALL_VARIABLES = [(r.name, v) for r in FMUS for v in r.variables]


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# -- validity ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", FMU_NAMES)
def test_fmpy_validation_reports_no_problem(fmu_dir: Path, name: str) -> None:
    assert validate_fmu(str(fmu_dir / f"{name}.fmu")) == []


def test_fmpy_validate_cli_reports_no_problem(friction_plant_fmu: Path) -> None:
    fmpy = Path(sys.executable).with_name("fmpy")
    done = subprocess.run(
        [str(fmpy), "validate", str(friction_plant_fmu)], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "No problems found" in done.stdout


# -- reproducible builds -------------------------------------------------------------------------
def test_builds_are_reproducible(fmu_dir: Path, tmp_path: Path) -> None:
    """Same sources, same bytes: FrictionPlant.fmu built twice into two folders (and by
    the session's build_all) is one archive; its GUID is the digest of its sources."""
    first = build_fmu("FrictionPlant", tmp_path / "a")
    second = build_fmu("FrictionPlant", tmp_path / "b")
    assert first == tmp_path / "a" / "FrictionPlant.fmu"
    assert sha256(first) == sha256(second) == sha256(fmu_dir / "FrictionPlant.fmu")
    assert is_current(first, "FrictionPlant")
    assert read_model_description(str(first)).guid == guid(fmu_digest("FrictionPlant"))
    assert not is_current(first, "PulseController")
    assert not is_current(tmp_path / "missing.fmu", "FrictionPlant")


@pytest.mark.parametrize("name", FMU_NAMES)
def test_session_builds_are_current_with_distinct_guids(fmu_dir: Path, name: str) -> None:
    path = fmu_dir / f"{name}.fmu"
    assert is_current(path, name)
    assert read_model_description(str(path)).guid == guid(fmu_digest(name))
    others = {guid(fmu_digest(n)) for n in FMU_NAMES if n != name}
    assert guid(fmu_digest(name)) not in others


def test_a_stale_fmu_is_not_current(fmu_dir: Path, tmp_path: Path) -> None:
    """An FMU whose model description says another GUID (another source) is stale."""
    copy = tmp_path / "FrictionPlant.fmu"
    copy.write_bytes((fmu_dir / "FrictionPlant.fmu").read_bytes())
    rewrite_fmu(copy, lambda root: root.set("guid", "{00000000-0000-0000-0000-000000000000}"))
    assert not is_current(copy, "FrictionPlant")
    (tmp_path / "junk.fmu").write_text("not a zip")
    assert not is_current(tmp_path / "junk.fmu", "FrictionPlant")


def test_archives_are_written_in_a_fixed_order_with_fixed_times(fmu_dir: Path) -> None:
    for name in FMU_NAMES:
        with zipfile.ZipFile(fmu_dir / f"{name}.fmu") as archive:
            infos = archive.infolist()
        assert [i.filename for i in infos] == sorted(i.filename for i in infos)
        assert {i.date_time for i in infos} == {(1980, 1, 1, 0, 0, 0)}


def test_a_full_disk_is_an_output_error_and_leaves_no_partial_fmu(tmp_path: Path,
                                                                    monkeypatch) -> None:
    import papwc.fmubuild.pythonfmu_build as pb

    copyfile = pb.shutil.copyfile

    def copy_then_fail(src, dst, **kw):
        if not str(dst).endswith(".fmu.tmp"):  # the build's own copies
            return copyfile(src, dst, **kw)
        Path(dst).write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device", str(dst))

    monkeypatch.setattr(pb.shutil, "copyfile", copy_then_fail)
    out = tmp_path / "out"
    with pytest.raises(OutputError, match="cannot write PapwcTrivial.fmu into .*No space left"):
        build_fmu("PapwcTrivial", out)
    assert OutputError.exit_code == 1  # an operating-system error, not bad input
    assert list(out.iterdir()) == []


def test_unknown_fmu_name_is_a_build_error() -> None:
    with pytest.raises(BuildError, match="no FMU named 'Nope'; FMUs: FrictionPlant, "
                                         "PulseController, PulseControllerPython, PapwcTrivial"):
        recipe("Nope")


# -- the model description says what the model layer's tables say ------------------------------
@pytest.fixture(scope="module")
def model_descriptions(fmu_dir: Path) -> dict[str, dict[str, ET.Element]]:
    """FMU name -> variable name -> <ScalarVariable> element."""
    return {
        name: {sv.get("name"): sv for sv in read_md_xml(fmu_dir / f"{name}.fmu")
               .iter("ScalarVariable")}
        for name in FMU_NAMES
    }


@pytest.mark.parametrize(("fmu", "var"), ALL_VARIABLES,
                         ids=[f"{f}.{v.name}" for f, v in ALL_VARIABLES])
def test_every_variable_has_the_metadata_of_its_table_entry(
    model_descriptions, fmu: str, var: Variable
) -> None:
    sv = model_descriptions[fmu][var.name]
    (typed,) = list(sv)
    assert typed.tag == var.type
    assert sv.get("causality") == var.causality
    assert sv.get("variability") == var.fmi_variability
    assert sv.get("description") == var.description and var.description
    if var.type == "Real":
        assert typed.get("unit") == var.unit, "the unit of the table"
        assert var.unit in UNIT_DEFINITIONS
    else:
        assert typed.get("unit") is None
    ranged = var.causality == "parameter" and var.type in ("Real", "Integer")
    # an excluded bound is written as the next double inside it (the FMU accepts it)
    low, high = var.min, var.max
    if var.type == "Real" and var.min_open and low is not None:
        low = math.nextafter(low, math.inf)
    if var.type == "Real" and var.max_open and high is not None:
        high = math.nextafter(high, -math.inf)
    for bound, value in (("min", low), ("max", high)):
        if ranged and value is not None:
            cast = float if var.type == "Real" else int
            assert typed.get(bound) == xml_number(cast(value)), bound
        else:
            assert typed.get(bound) is None, bound
    if var.type == "Real" and var.nominal is not None:
        assert float(typed.get("nominal")) == var.nominal
    if var.causality == "output":
        assert sv.get("initial") == (var.initial or "exact")
    if var.causality == "output" and var.initial == "calculated":
        assert typed.get("start") is None
    else:
        assert typed.get("start") == xml_number(var.fmi_start)


@pytest.mark.parametrize("name", FMU_NAMES)
def test_units_outputs_and_initial_unknowns(fmu_dir: Path, name: str) -> None:
    root = read_md_xml(fmu_dir / f"{name}.fmu")
    variables = recipe(name).variables
    used = {v.unit for v in variables if v.type == "Real"}
    units = {u.get("name"): u for u in root.iter("Unit")}
    assert set(units) == used
    for unit, element in units.items():
        base = element.find("BaseUnit")
        exponents = {} if base is None else {k: int(e) for k, e in base.attrib.items()}
        assert exponents == UNIT_DEFINITIONS[unit]
    scalars = [sv.get("name") for sv in root.iter("ScalarVariable")]
    assert scalars == [v.name for v in variables]  # value references in table order
    index = {n: str(i + 1) for i, n in enumerate(scalars)}
    outputs = root.find("ModelStructure/Outputs")
    assert [u.get("index") for u in outputs] == [index[v.name] for v in variables
                                                 if v.causality == "output"]
    assert all(u.get("dependencies") == "" for u in outputs)  # no direct feedthrough
    calculated = [index[v.name] for v in variables if v.initial == "calculated"]
    unknowns = root.find("ModelStructure/InitialUnknowns")
    assert [u.get("index") for u in (unknowns if unknowns is not None else [])] == calculated
    assert root.get("generationDateAndTime") is None


def test_plant_model_description_contract(friction_plant_fmu: Path) -> None:
    md = read_model_description(str(friction_plant_fmu))
    assert md.coSimulation.modelIdentifier == "FrictionPlant"
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    assert md.coSimulation.canGetAndSetFMUstate
    assert md.coSimulation.canSerializeFMUstate
    units = {u.name: u for u in md.unitDefinitions}
    assert set(units) == {"kg", "N", "N.s/m", "m", "m/s", "N/m", "s", "rad", "1"}
    assert (units["N"].baseUnit.kg, units["N"].baseUnit.m, units["N"].baseUnit.s) == (1, 1, -2)
    assert (units["N.s/m"].baseUnit.kg, units["N.s/m"].baseUnit.s) == (1, -1)
    assert (units["m/s"].baseUnit.m, units["m/s"].baseUnit.s) == (1, -1)
    expected = {
        "m": ("parameter", "fixed", "kg", "150"),
        "f_c": ("parameter", "fixed", "N", "100"),
        "f_s": ("parameter", "fixed", "N", "130"),
        "c": ("parameter", "fixed", "N.s/m", "700"),
        "x0": ("parameter", "fixed", "m", "0"),
        "v0": ("parameter", "fixed", "m/s", "0"),
        "x_resolution": ("parameter", "fixed", "m", "0"),
        "u": ("input", "continuous", "N", "0"),
        "x": ("output", "continuous", "m", None),
        "v": ("output", "continuous", "m/s", None),
        "x_meas": ("output", "continuous", "m", None),
        "x_d": ("output", "continuous", "m", None),
        "x_d_meas": ("output", "continuous", "m", None),
        "x_d_resolution": ("parameter", "fixed", "m", "0"),
        "x_d_noise_std": ("parameter", "fixed", "m", "0"),
    }
    variables = {v.name: v for v in md.modelVariables}
    deviations = {"v_s", "delta_s", "sigma_0", "sigma_1", "ripple", "ripple_period",
                  "ripple_phase", "f_s_spread", "seed", "tau_u", "m_d", "k_t", "c_t",
                  "noise_std"}
    assert set(variables) == set(expected) | {"stuck"} | deviations
    assert set(variables) == {v.name for v in PLANT_VARIABLES}
    for name, (causality, variability, unit, start) in expected.items():
        v = variables[name]
        assert (v.type, v.causality, v.variability) == ("Real", causality, variability)
        assert v.unit == unit, name
        if start is None:  # calculated from x0, v0, x_resolution: no start value
            assert v.start is None, name
        else:
            assert float(v.start) == float(start), name
    assert variables["stuck"].type == "Boolean"
    assert variables["stuck"].causality == "output"
    assert variables["stuck"].start is None
    for v in md.modelVariables:
        assert v.description, f"variable {v.name} has no description"
        if v.causality == "output":
            assert v.initial == "calculated", v.name
    # ranges where the physics is exact in double precision (papwc.model.plant)
    base = set(expected) - {"u", "x", "v", "x_meas", "x_d", "x_d_meas"}
    assert {n: v.min for n, v in variables.items() if v.min is not None and n in base} == {
        "m": "1e-06", "f_c": "0.0", "f_s": "0.0", "c": "0.0", "x_resolution": "0.0",
        "x0": "-1000000.0", "v0": "-1000000.0", "x_d_resolution": "0.0",
        "x_d_noise_std": "0.0"}
    assert {n: v.max for n, v in variables.items() if v.max is not None and n in base} == {
        "m": "1000000000.0", "f_c": "1000000000.0", "f_s": "1000000000.0",
        "c": "1000000000.0", "x_resolution": "1.0", "x0": "1000000.0", "v0": "1000000.0",
        "x_d_resolution": "1.0", "x_d_noise_std": "1.0"}
    # every deviation is bounded, and its default leaves the plant of the paper
    assert all(variables[n].min is not None and variables[n].max is not None
               for n in deviations)
    de = md.defaultExperiment
    assert (float(de.startTime), float(de.stopTime), float(de.stepSize)) == (0.0, 1.0, 0.01)


# -- completing a model description refuses what does not fit, and leaves the FMU as it was ----
@pytest.mark.parametrize(
    ("change", "problem"),
    [
        ("unit", "unknown unit(s) ['lb']"),
        ("extra", "differ in ['y']"),
        ("type", "variable stuck is a Boolean, the table says Real"),
        ("missing", "differ in ['c']"),
    ],
)
def test_completing_the_model_description_refuses_with_a_clear_error(
    friction_plant_fmu: Path, tmp_path: Path, change: str, problem: str
) -> None:
    table = list(PLANT_VARIABLES)
    by_name = {v.name: i for i, v in enumerate(table)}
    if change == "unit":
        table[by_name["m"]] = Variable("m", "Mass", "lb", 150.0)
    elif change == "extra":
        table.append(Variable("y", "extra", "m", 0.0, causality="output"))
    elif change == "type":
        table[by_name["stuck"]] = Variable("stuck", "stuck", "1", 1.0, causality="output")
    else:
        del table[by_name["c"]]
    copy = tmp_path / "FrictionPlant.fmu"
    copy.write_bytes(friction_plant_fmu.read_bytes())
    with pytest.raises(BuildError, match="FrictionPlant.fmu") as info:
        rewrite_fmu(copy, lambda root: complete_model_description(root, table, where=copy.name))
    assert problem in str(info.value)
    assert copy.read_bytes() == friction_plant_fmu.read_bytes()


def test_rewriting_without_an_edit_keeps_the_archive(friction_plant_fmu: Path,
                                                     tmp_path: Path) -> None:
    copy = tmp_path / "FrictionPlant.fmu"
    copy.write_bytes(friction_plant_fmu.read_bytes())
    rewrite_fmu(copy)
    assert copy.read_bytes() == friction_plant_fmu.read_bytes()
    (tmp_path / "broken.fmu").write_text("not a zip")
    with pytest.raises(BuildError, match="cannot read modelDescription.xml"):
        rewrite_fmu(tmp_path / "broken.fmu")


@pytest.mark.parametrize(
    ("value", "text"),
    [(150.0, "150.0"), (1e-6, "1e-06"), (0.1, "0.1"), (float("inf"), "INF"),
     (float("-inf"), "-INF"), (float("nan"), "NaN"), (3, "3"), (True, "true"), (False, "false"),
     ("papwc", "papwc")],
)
def test_xml_number_round_trips(value, text):
    assert xml_number(value) == text
    if isinstance(value, float) and value == value:
        assert float(text.replace("INF", "inf")) == value


# -- build errors --------------------------------------------------------------------------------
def test_build_of_a_missing_script_is_a_build_error(tmp_path: Path) -> None:
    with pytest.raises(BuildError, match="Missing.py does not exist"):
        build_pythonfmu(FmuSource(tmp_path / "Missing.py", ()), tmp_path)


def test_a_model_that_fails_to_build_is_a_build_error(tmp_path: Path) -> None:
    script = tmp_path / "Broken.py"
    script.write_text(
        "from pythonfmu import Fmi2Slave\n\n\n"
        "class Broken(Fmi2Slave):\n"
        "    def __init__(self, **kwargs):\n"
        "        super().__init__(**kwargs)\n"
        "        raise ValueError('no variables here')\n\n"
        "    def do_step(self, current_time, step_size):\n"
        "        return True\n"
    )
    with pytest.raises(BuildError, match="ValueError: no variables here"):
        build_pythonfmu(FmuSource(script, ()), tmp_path / "out")
    assert "Broken" not in sys.modules
    assert not (tmp_path / "out" / "Broken.fmu").exists()


def test_a_bundle_needs_a_package_name(tmp_path: Path) -> None:
    script = tmp_path / "Model.py"
    script.write_text("")
    with pytest.raises(BuildError, match="a bundle needs a package name"):
        build_pythonfmu(FmuSource(script, (), bundle={"model": PACKAGE_DIR / "model"}), tmp_path)
    with pytest.raises(BuildError, match="source .*nowhere does not exist"):
        build_pythonfmu(FmuSource(script, (), package="p", bundle={"model": tmp_path / "nowhere"}),
                        tmp_path)


# -- what each FMU bundles -----------------------------------------------------------------------
def _bundled_files() -> list[tuple[str, str, Path]]:
    """(FMU, path in the archive, source file) for every bundled source file."""
    out = []
    for r in FMUS:
        for sub in r.subpackages:
            for source in sorted((PACKAGE_DIR / sub).rglob("*.py")):
                rel = source.relative_to(PACKAGE_DIR).as_posix()
                out.append((r.name, f"resources/{r.package}/{rel}", source))
    return out


BUNDLED = _bundled_files()


def pythonfmu_path(fmu_dir: Path, name: str) -> Path:
    """The pythonfmu build of FMU ``name`` (FrictionPlant's is in ``fmu_dir/pythonfmu``)."""
    separate = fmu_dir / "pythonfmu" / f"{name}.fmu"
    return separate if separate.is_file() else fmu_dir / f"{name}.fmu"


@pytest.mark.parametrize(("fmu", "member", "source"), BUNDLED,
                         ids=[f"{f}:{m.split('/', 2)[2]}" for f, m, _ in BUNDLED])
def test_bundled_code_is_byte_identical_to_the_package(fmu_dir: Path, fmu: str, member: str,
                                                       source: Path) -> None:
    with zipfile.ZipFile(pythonfmu_path(fmu_dir, fmu)) as archive:
        assert archive.read(member) == source.read_bytes()


@pytest.mark.parametrize("name", [r.name for r in FMUS if r.python])
def test_each_fmu_bundles_its_own_packages_only(fmu_dir: Path, name: str) -> None:
    r = recipe(name)
    with zipfile.ZipFile(pythonfmu_path(fmu_dir, name)) as archive:
        names = archive.namelist()
    bundled = {n.split("/")[1] for n in names if n.startswith("resources/") and n.count("/") > 1
               and not n.startswith("resources/pythonfmu/")}
    assert bundled == ({r.package} if r.package else set())
    assert f"resources/{name}.py" in names
    assert not any(n.startswith("resources/papwc/") or "papwc_stickslip" in n for n in names)
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)
    subpackages = {n.split("/")[2] for n in names if r.package and
                   n.startswith(f"resources/{r.package}/") and n.count("/") > 2}
    assert subpackages == set(r.subpackages)
    assert ("documentation/readme.md" in names) == bool(r.documentation)
    script = (r.folder / f"{name}.py").read_bytes()
    with zipfile.ZipFile(pythonfmu_path(fmu_dir, name)) as archive:
        assert archive.read(f"resources/{name}.py") == script


def test_the_plant_fmu_holds_the_physics(pythonfmu_plant_fmu: Path) -> None:
    with zipfile.ZipFile(pythonfmu_plant_fmu) as archive:
        bundled = archive.read("resources/papwc_friction_plant/model/stickslip.py")
        readme = archive.read("documentation/readme.md")
    assert bundled == (PACKAGE_DIR / "model" / "stickslip.py").read_bytes()
    assert readme == recipe("FrictionPlant").documentation[0].read_bytes()
