"""The native PulseController.fmu (the C controller, built by zig for win64, linux64, darwin64).

- the Python controllers' numbers, bit for bit, through fmpy, over random settings (drawn
  inside their ranges) and random readings of a closed loop, with FMU states got, serialized,
  set into another instance and set back in the middle (hypothesis);
- every refusal returns fmi2Error (fmi2Discard for a step: a reading that is not finite, a
  step other than T) with one logged message, never fmi2OK; a kind it does not implement is
  refused naming PulseControllerPython.fmu;
- the binaries of both native FMUs: every fmi2 function exported; win64 imports KERNEL32 and
  the C runtime only; darwin64 declares macOS 10.13 (x86_64) and 11.0 (arm64) as its minimum;
- no Python in the host: a C host (tests/c_host/fmu_host.c, the system cc) runs the
  controller FMU alone and gives the Python controller's forces; the ecos command line runs
  ClosedLoop.ssp (both native FMUs) under ``env -i PATH=/usr/bin:/bin`` and gives
  ``papwc cosim``'s numbers to the CSV's digits (and x to 1e-12 m through a probe);
- 10,000 instantiate/initialize/step/free cycles grow the RSS by less than 1 MB.

Each test that measures prints its figure (``pytest -s``: lines ``native controller:``).
"""

from __future__ import annotations

import ctypes
import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from harness import FMI2_DISCARD, FMI2_ERROR, FmuInstance, settings_start_values
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from papwc.controllers import make_controller
from papwc.controllers.settings import ControllerSettings
from papwc.fmubuild.native_tables import NATIVE_KINDS
from papwc.model.controller_settings import KIND_CODES
from papwc.model.dynamics import Plant

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parent.parent / "unit"))
import test_native_fmu as plant_tests  # noqa: E402
from test_native_controller import controller_settings, plant_params  # noqa: E402

FMI2_OK = 0
T = 0.01
OUTPUTS = ("u", "b_hat", "f_c_hat", "pulses", "mode", "f_low", "outcome", "outcome_reason")
PROJECT_DIR = Path(__file__).resolve().parents[2]


def report(what: str, value: object) -> None:
    print(f"\nnative controller: {what}: {value}")


def bits(value) -> str:
    return value.hex() if isinstance(value, float) else repr(value)


def fmu_outputs(fmu: FmuInstance) -> list[str]:
    return [bits(fmu.get(name)) for name in OUTPUTS]


def python_outputs(controller, u: float) -> list[str]:
    out = controller.outputs()
    return [bits(u)] + [bits(out[name]) for name in OUTPUTS[1:]]


def start(fmu: FmuInstance, s: ControllerSettings, T: float, x_ref: float) -> None:
    fmu.init(**settings_start_values(s, T), x_ref_offset=x_ref)


# --- the Python controllers' numbers ---------------------------------------------------------

@settings(max_examples=24, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data(), kind=st.sampled_from(NATIVE_KINDS),
       T=st.sampled_from((0.01, 0.002, 0.001)),
       params=plant_params(), n=st.integers(10, 250), cut=st.floats(0.0, 1.0),
       x_ref=st.sampled_from((1e-2, 1e-3, -5e-5)))
def test_the_native_fmu_is_the_python_controller_bit_for_bit(
        pulse_controller_unzipped: Path, data, kind: str, T: float, params: dict, n: int,
        cut: float, x_ref: float) -> None:
    """Closed around the model layer's plant; the FMU's state got, serialized, set into an
    instance made with other parameters at ``cut`` and set back afterwards: every output
    of every step, of all three runs, the Python controller's."""
    s = data.draw(controller_settings(kind, T))
    python = make_controller(s, T)
    plant = Plant(params)
    fmu = FmuInstance(pulse_controller_unzipped, "controller")
    other = FmuInstance(pulse_controller_unzipped, "other")
    try:
        start(fmu, s, T, x_ref)
        other.init(**settings_start_values(ControllerSettings(kind="pwc"), 0.02), x_ref=0.5)
        at = int(cut * n)
        readings, expected = [], []
        for k in range(n):
            x = plant.x_meas()
            if k == at:
                saved = fmu.fmu.getFMUstate()
                restored = other.fmu.deSerializeFMUstate(fmu.fmu.serializeFMUstate(saved))
                other.fmu.setFMUstate(restored)
                other.fmu.freeFMUstate(restored)
                other.t = fmu.t
                t_saved = fmu.t
            u = python.update(k * T, x, x_ref)
            fmu.advance(T, x_meas=x)
            assert fmu_outputs(fmu) == python_outputs(python, u), (k, x)
            if k >= at:
                readings.append(x)
                expected.append(fmu_outputs(fmu))
            assert plant.step(u, T) is None
        for x, then in zip(readings, expected, strict=True):
            other.advance(T, x_meas=x)
            assert fmu_outputs(other) == then
        fmu.fmu.setFMUstate(saved)
        fmu.fmu.freeFMUstate(saved)
        fmu.t = t_saved
        for x, then in zip(readings, expected, strict=True):
            fmu.advance(T, x_meas=x)
            assert fmu_outputs(fmu) == then
        assert other.get("kind") == kind and other.get("T") == T
        assert fmu.logged(FMI2_ERROR) == other.logged(FMI2_ERROR) == []
    finally:
        fmu.close()
        other.close()


@pytest.mark.parametrize("in_position", [None, False])
def test_the_pids_window_goes_on_from_a_state_serialized_in_a_hold(
        pulse_controller_unzipped: Path, in_position: bool | None) -> None:
    """The PID at 1 kHz, tolerance 1 um, on a noisy encoder of 0.1 um counts (0.2 um rms), its
    in-position window at its default (on) and off: the FMU's state got and serialized at the
    first sample of its first hold (the window on; else at 1 s), set into an instance made with
    other parameters: every output of 2 s of both the Python PID's, bit for bit."""
    T_pid, x_ref = 0.001, 1e-3
    s = ControllerSettings(kind="pid", tolerance=1e-6, in_position=in_position)
    python = make_controller(s, T_pid)
    plant = Plant({"noise_std": 2e-7, "x_resolution": 1e-7, "seed": 3})
    fmu = FmuInstance(pulse_controller_unzipped, "controller")
    other = FmuInstance(pulse_controller_unzipped, "other")
    try:
        start(fmu, s, T_pid, x_ref)
        other.init(**settings_start_values(ControllerSettings(kind="pwc"), 0.02), x_ref=0.5)
        saved, readings, expected, held = None, [], [], 0
        for k in range(2000):
            x = plant.x_meas()
            if saved is None and (python.holding or k == 1000):
                held = int(python.holding)
                saved = fmu.fmu.getFMUstate()
                restored = other.fmu.deSerializeFMUstate(fmu.fmu.serializeFMUstate(saved))
                other.fmu.setFMUstate(restored)
                other.fmu.freeFMUstate(restored)
                fmu.fmu.freeFMUstate(saved)
                other.t = fmu.t
            u = python.update(k * T_pid, x, x_ref)
            fmu.advance(T_pid, x_meas=x)
            assert fmu_outputs(fmu) == python_outputs(python, u), (k, x)
            if saved is not None:
                readings.append(x)
                expected.append(fmu_outputs(fmu))
            assert plant.step(u, T_pid) is None
        assert held == (in_position is None) and python.outcome == 1  # settled
        for x, then in zip(readings, expected, strict=True):
            other.advance(T_pid, x_meas=x)
            assert fmu_outputs(other) == then
        assert fmu.logged(FMI2_ERROR) == other.logged(FMI2_ERROR) == []
    finally:
        fmu.close()
        other.close()


# --- refusals ----------------------------------------------------------------------------------

def refused(call) -> int:
    """The status of a call expected to be refused (fmpy raises for any status but OK)."""
    with pytest.raises(FMICallException) as info:
        call()
    return info.value.status


@pytest.mark.parametrize("logging", [True, False])
def test_each_refusal_is_an_error_or_a_discard_with_one_message(
        pulse_controller_unzipped: Path, friction_plant_unzipped: Path, logging: bool) -> None:
    fmu = FmuInstance(pulse_controller_unzipped, "controller", logging=logging)
    vr = {name: v.valueReference for name, v in fmu.vars.items()}
    try:
        fmu.fmu.setupExperiment(startTime=0.0)
        fmu.fmu.enterInitializationMode()
        fmu.set("K_c", 2.5)  # out of its range
        assert refused(fmu.fmu.exitInitializationMode) == FMI2_ERROR
        fmu.set("K_c", 0.8)
        for kind in ("exact", "hybrid"):  # not in the native build
            fmu.set("kind", kind)
            assert refused(fmu.fmu.exitInitializationMode) == FMI2_ERROR
        fmu.set("kind", "papwc")
        fmu.set("kind_code", 1)  # names another kind than the String
        assert refused(fmu.fmu.exitInitializationMode) == FMI2_ERROR
        fmu.set("kind_code", 2)
        fmu.set("x_ref_offset", 0.01)
        fmu.fmu.exitInitializationMode()  # corrected: accepted
        fmu.advance(T, x_meas=0.0)
        before = fmu_outputs(fmu)
        cases = {
            "parameter after initialization": lambda: fmu.fmu.setReal([vr["K_c"]], [0.5]),
            "String after initialization": lambda: fmu.fmu.setString([vr["kind"]], ["pwc"]),
            "output set": lambda: fmu.fmu.setReal([vr["u"]], [1.0]),
            "no such variable": lambda: fmu.fmu.getReal([999]),
            "wrong type": lambda: fmu.fmu.getInteger([vr["K_c"]]),
            "communication point that jumps": lambda: fmu.fmu.doStep(fmu.t + 0.5, T),
        }
        for what, call in cases.items():
            assert refused(call) == FMI2_ERROR, what
        for x in (math.nan, math.inf):
            fmu.set("x_meas", x)
            assert refused(lambda: fmu.fmu.doStep(fmu.t, T)) == FMI2_DISCARD
        fmu.set("x_meas", 0.0)
        for h in (0.02, 0.0, math.nan):
            assert refused(lambda h=h: fmu.fmu.doStep(fmu.t, h)) == FMI2_DISCARD
        assert fmu_outputs(fmu) == before  # every refusal left the state as it was
        # a state that does not fit: another FMU's, another size, a controller made from
        # other parameters than the state's
        state = fmu.fmu.getFMUstate()
        data = bytearray(fmu.fmu.serializeFMUstate(state))
        plant = FmuInstance(friction_plant_unzipped, "plant")
        plant_state = plant.fmu.serializeFMUstate(plant.fmu.getFMUstate())
        plant.close(terminate=False)
        assert refused(lambda: fmu.fmu.deSerializeFMUstate(bytes(plant_state))) == FMI2_ERROR
        assert refused(lambda: fmu.fmu.deSerializeFMUstate(bytes(data[:-8]))) == FMI2_ERROR
        broken = bytearray(data)
        at = broken.find(struct.pack("<d", 0.8))  # K_c in the parameters, not in the controller
        assert at > 0
        broken[at:at + 8] = struct.pack("<d", 0.5)
        assert refused(lambda: fmu.fmu.deSerializeFMUstate(bytes(broken))) == FMI2_ERROR
        fmu.fmu.freeFMUstate(state)
        fmu.advance(T, x_meas=0.0)  # the instance keeps working
        if logging:
            errors = fmu.logged(FMI2_ERROR)
            assert any("parameter K_c = 2.5: must satisfy 0 < K_c < 2 (Eq. (6))" in e
                       for e in errors)
            for kind in ("exact", "hybrid"):
                assert sum(f"parameter kind = '{kind}': must be one of 'papwc', 'pid', 'pwc' "
                           "(PulseController.fmu is the C controller; 'exact', 'dual_loop' and "
                           "'hybrid' are in PulseControllerPython.fmu, which papwc build makes "
                           "beside it)" in e for e in errors) == 1, kind
            assert any("name different controllers" in e for e in errors)
            assert any("it was made from other parameters" in e for e in errors)
            discards = fmu.logged(FMI2_DISCARD)
            assert any("input x_meas = nan m is not finite" in e for e in discards)
            assert any("the communication step size 0.02 s differs from the sample period "
                       "T = 0.01 s" in e for e in discards)
        else:
            assert fmu.messages == []
    finally:
        fmu.close()


@pytest.mark.parametrize(("kind_code", "kind"), [(3, "exact"), (6, "hybrid")])
def test_a_refused_initialization_is_one_line_on_stderr(pulse_controller_fmu: Path,
                                                        tmp_path: Path, kind_code: int,
                                                        kind: str) -> None:
    """fmpy simulate with logging off (its default): the refusal of a kind of
    PulseControllerPython.fmu only is one line naming it, not silence."""
    import test_fmu_hosts_metadata as metadata

    assert KIND_CODES[kind_code - 1] == kind and kind not in NATIVE_KINDS
    done = metadata.fmpy_cli("simulate", str(pulse_controller_fmu), "--start-values",
                             "kind_code", str(kind_code), "--stop-time", "0.05",
                             "--output-file", str(tmp_path / "out.csv"))
    assert done.returncode != 0
    lines = [line for line in done.stderr.splitlines() if line.startswith("PulseController ")]
    assert len(lines) == 1, done.stderr
    assert f"parameter kind = '{kind}': must be one of 'papwc', 'pid', 'pwc'" in lines[0]
    assert "are in PulseControllerPython.fmu" in lines[0]
    assert "initialization refused (fmi2Error)" in lines[0]


# --- the binaries -------------------------------------------------------------------------------

@pytest.fixture(params=["FrictionPlant", "PulseController"])
def native_fmu(request, friction_plant_fmu: Path, pulse_controller_fmu: Path) -> Path:
    return {"FrictionPlant": friction_plant_fmu, "PulseController": pulse_controller_fmu}[
        request.param]


def binary(fmu: Path, platform: str, suffix: str) -> bytes:
    with zipfile.ZipFile(fmu) as archive:
        return archive.read(f"binaries/{platform}/{fmu.stem}{suffix}")


def _macho_minimum(data: bytes, offset: int) -> tuple[int, int]:
    """(major, minor) of the oldest macOS a thin Mach-O at ``offset`` declares."""
    _, _, _, _, ncmds, _, _, _ = struct.unpack_from("<IiiIIIII", data, offset)
    pos = offset + 32
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, pos)
        if cmd == 0x32:  # LC_BUILD_VERSION: platform, minos, sdk
            _, minos = struct.unpack_from("<II", data, pos + 8)
            return minos >> 16, (minos >> 8) & 0xFF
        if cmd == 0x24:  # LC_VERSION_MIN_MACOSX: version, sdk
            (version,) = struct.unpack_from("<I", data, pos + 8)
            return version >> 16, (version >> 8) & 0xFF
        pos += size
    raise AssertionError("no minimum macOS version declared")


def test_the_macos_binaries_declare_10_13_and_11_and_export_every_fmi2_function(
        native_fmu: Path) -> None:
    data = binary(native_fmu, "darwin64", ".dylib")
    magic, count = struct.unpack_from(">II", data, 0)
    assert magic == 0xCAFEBABE and count == 2
    minimum = {}
    for i in range(count):
        cputype, _, offset, _, _ = struct.unpack_from(">iiIII", data, 8 + 20 * i)
        _, dylibs, exported = plant_tests._macho_thin(data, offset)
        assert dylibs == ["/usr/lib/libSystem.B.dylib"], dylibs
        assert {"_" + f for f in plant_tests.fmi2_functions()} <= exported
        minimum[cputype] = _macho_minimum(data, offset)
    report(f"{native_fmu.stem} darwin64 minimum macOS (x86_64, arm64)",
           (minimum[0x01000007], minimum[0x0100000C]))
    assert minimum == {0x01000007: (10, 13), 0x0100000C: (11, 0)}


def test_the_windows_binary_imports_only_kernel32_and_the_c_runtime(native_fmu: Path) -> None:
    pefile = pytest.importorskip("pefile")
    pe = pefile.PE(data=binary(native_fmu, "win64", ".dll"))
    dlls = sorted(entry.dll.decode() for entry in pe.DIRECTORY_ENTRY_IMPORT)
    report(f"{native_fmu.stem} win64 imports", dlls)
    for dll in dlls:
        name = dll.lower()
        assert name in ("kernel32.dll", "msvcrt.dll", "ucrtbase.dll") or name.startswith(
            "api-ms-win-crt-"), dll
    exported = {e.name.decode() for e in pe.DIRECTORY_ENTRY_EXPORT.symbols if e.name}
    assert set(plant_tests.fmi2_functions()) <= exported


def test_the_linux_binary_needs_glibc_2_17_and_exports_every_fmi2_function(
        pulse_controller_fmu: Path, pulse_controller_unzipped: Path) -> None:
    needed, versions = plant_tests._elf_needs(binary(pulse_controller_fmu, "linux64", ".so"))
    newest = max(tuple(int(p) for p in v.split("_")[1].split(".")) for v in versions)
    assert newest <= (2, 17) and set(needed) <= {"libc.so.6", "libm.so.6"}
    library = ctypes.CDLL(str(pulse_controller_unzipped / "binaries" / "linux64" /
                              "PulseController.so"))
    assert [f for f in plant_tests.fmi2_functions() if not hasattr(library, f)] == []
    assert hasattr(library, "papwc_controller_api")
    assert not hasattr(library, "pc_update")  # the library's own symbols stay hidden


# --- no Python in the host ---------------------------------------------------------------------

def _cc() -> str:
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        if os.environ.get("CI") == "true":
            pytest.fail("a C compiler is required in CI")
        pytest.skip("no C compiler")
    return cc


def test_a_c_host_runs_the_controller_fmu_alone(pulse_controller_unzipped: Path,
                                                tmp_path: Path) -> None:
    """tests/c_host/fmu_host.c (dlopen, no Python in its process) sets PAPWC's settings of the
    paper, feeds the readings of the Python loop and prints the forces and outputs: the
    Python controller's, bit for bit (C's %a is the exact bits)."""
    import fmpy

    host = tmp_path / "fmu_host"
    done = subprocess.run([_cc(), "-std=c99", "-O2", "-Wall", "-I",
                           str(Path(fmpy.__file__).parent / "c-code"), "-o", str(host),
                           str(PROJECT_DIR / "tests" / "c_host" / "fmu_host.c"), "-ldl"],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    md = read_model_description(str(pulse_controller_unzipped))
    variables = {v.name: v for v in md.modelVariables}
    s = ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8, f_c_est=80.0,
                           safeguards=False)
    args = []
    for name, value in {**settings_start_values(s, T), "x_ref_offset": 0.01}.items():
        var = variables[name]
        if var.type == "String":  # the host sets no String: the kind's code
            args.append(f"i:{variables['kind_code'].valueReference}="
                        f"{KIND_CODES.index(value) + 1}")
        elif var.type == "Boolean":
            args.append(f"b:{var.valueReference}={'true' if value else 'false'}")
        elif var.type == "Integer":
            args.append(f"i:{var.valueReference}={int(value)}")
        else:
            args.append(f"r:{var.valueReference}={float(value)!r}")
    outputs = [f"{variables[n].valueReference}{'i' if variables[n].type == 'Integer' else 'r'}"
               for n in OUTPUTS]
    python = make_controller(s, T)
    plant = Plant({"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0})
    readings, expected = [], []
    for k in range(400):
        x = plant.x_meas()
        u = python.update(k * T, x, 0.01)
        readings.append(f"{variables['x_meas'].valueReference} {x!r}")
        expected.append(python_outputs(python, u))
        assert plant.step(u, T) is None
    binary_path = pulse_controller_unzipped / "binaries" / "linux64" / "PulseController.so"
    run = subprocess.run([str(host), str(binary_path), md.guid, repr(T), *args, "--",
                          *outputs], input="\n".join(readings) + "\n", capture_output=True,
                         text=True, timeout=120, env={"PATH": "/usr/bin:/bin"}, check=False)
    assert run.returncode == 0, run.stderr
    got = []
    for line in run.stdout.splitlines():
        fields = line.split()
        got.append([bits(float.fromhex(f)) if "p" in f or "nan" in f or "inf" in f
                    else repr(int(f)) for f in fields])
    assert got == expected
    assert int(run.stdout.splitlines()[-1].split()[3]) > 3  # pulses


def test_ecos_runs_the_closed_loop_with_no_python_as_papwc_cosim(
        fmu_dir: Path, tmp_path: Path) -> None:
    """ClosedLoop.ssp as papwc build writes it (the native FrictionPlant.fmu under the native
    PulseController.fmu) in the ecos command line under ``env -i PATH=/usr/bin:/bin``: every
    value of the controller and the plant in ecos's CSV (6 decimals) is ``papwc cosim``'s
    rounded to those digits, and x, carried at all its digits into a second plant's input,
    is papwc cosim's to 1e-12 m."""
    sys.path.insert(0, str(Path(__file__).parent))
    import test_fmi_hosts as hosts

    try:
        import ecospy
    except (ImportError, OSError) as exc:
        if os.environ.get("CI") == "true":
            pytest.fail(f"ecos is required in CI: {exc}")
        pytest.skip(f"ecospy cannot be imported: {exc}")
    ecos = tmp_path / "ecos"
    shutil.copy(Path(ecospy.__file__).parent / "binaries" / "ecos", ecos)
    ecos.chmod(0o755)
    from papwc.fmubuild.ssp_writer import build_closed_loop_ssp

    ssp = build_closed_loop_ssp(tmp_path / "ssp", PROJECT_DIR / "scenarios" / "paper.toml",
                                fmu_dir / "FrictionPlant.fmu", fmu_dir / "PulseController.fmu")
    with zipfile.ZipFile(ssp) as archive:
        assert "resources/PulseController.fmu" in archive.namelist()
    probed = _with_sink(ssp, tmp_path / "probed.ssp", hosts.SCALE)
    run = tmp_path / "run"
    run.mkdir()
    done = subprocess.run(["env", "-i", "PATH=/usr/bin:/bin", str(ecos), "simulate", "--path",
                           str(probed), "--stepSize", "0.01", "--stopTime", "2",
                           "--parameterSet", "scenario", "-l", "warn"], cwd=run,
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    (path,) = run.glob("*.csv")
    rows = hosts.read_csv(path)
    cosim = tmp_path / "cosim"
    done = subprocess.run([sys.executable, "-m", "papwc.cli", "cosim", str(ssp), "--out",
                           str(cosim)], capture_output=True, text=True, timeout=300,
                          check=False)
    assert done.returncode == 0, done.stderr
    (reference_csv,) = cosim.glob("*.csv")
    reference = hosts.read_csv(reference_csv)
    # ecos writes t = 0 to 1.99 s (the rows before its last step), papwc cosim to 2 s
    assert len(rows) == len(reference) - 1 == 200
    compared = 0
    for ours, theirs in zip(rows, reference, strict=False):
        assert abs(float(ours["time"]) - float(theirs["time"])) < 1e-9
        for name, value in theirs.items():
            component, _, variable = name.partition(".")
            for key in (f"{component}::{variable}[REAL]", f"{component}::{variable}[INT]"):
                if key in ours:
                    expected = (f"{float(value):.6f}" if key.endswith("[REAL]")
                                else str(int(float(value))))
                    assert ours[key] == expected, (name, theirs["time"] if "time" in theirs
                                                   else "", value, ours[key])
                    compared += 1
    xs = [float(r["sink::u[REAL]"]) / hosts.SCALE for r in rows]
    error = max(abs(a - float(b["plant.x"])) for a, b in zip(xs, reference, strict=False))
    report("ecos command line, env -i PATH=/usr/bin:/bin, ClosedLoop.ssp: values compared",
           compared)
    report("ecos command line, ClosedLoop.ssp, max |x - x_cosim| (m)", error)
    assert compared > 2000 and error <= 1e-12
    assert int(rows[-1]["controller::pulses[INT]"]) > 3


def _with_sink(ssp: Path, target: Path, scale: float) -> Path:
    """``ssp`` with a second FrictionPlant fed ``plant.x`` times ``scale`` (its input u is in
    ecos's CSV: x at all its digits, with no Python FMU)."""
    with zipfile.ZipFile(ssp) as src:
        members = {name: src.read(name) for name in src.namelist()}
    ssd = members["SystemStructure.ssd"].decode()
    sink = ('<ssd:Component name="sink" type="application/x-fmu-sharedlibrary" '
            'source="resources/FrictionPlant.fmu"><ssd:Connectors><ssd:Connector name="u" '
            'kind="input"><ssc:Real/></ssd:Connector></ssd:Connectors></ssd:Component>')
    ssd = ssd.replace("</ssd:Elements>", sink + "</ssd:Elements>", 1)
    ssd = ssd.replace("</ssd:Connections>", (
        '<ssd:Connection startElement="plant" startConnector="x" endElement="sink" '
        f'endConnector="u"><ssc:LinearTransformation factor="{scale!r}" offset="0.0"/>'
        "</ssd:Connection></ssd:Connections>"), 1)
    members["SystemStructure.ssd"] = ssd.encode()
    with zipfile.ZipFile(target, "w") as dst:
        for name, data in members.items():
            dst.writestr(name, data)
    return target


# --- memory -------------------------------------------------------------------------------------

@pytest.mark.skipif(not Path("/proc/self/statm").is_file(), reason="needs /proc (Linux)")
def test_ten_thousand_instances_do_not_grow_the_memory(pulse_controller_unzipped: Path) -> None:
    md = read_model_description(str(pulse_controller_unzipped))
    library = plant_tests.fmi_library(pulse_controller_unzipped)
    guid = md.guid.encode()
    variables = {v.name: v.valueReference for v in md.modelVariables}
    vr = (ctypes.c_uint * 2)(variables["x_ref_offset"], variables["x_meas"])
    values = (ctypes.c_double * 2)(0.01, 0.0)
    kind = (ctypes.c_char_p * 1)(b"papwc")
    kind_vr = (ctypes.c_uint * 1)(variables["kind"])

    def cycle() -> None:
        c = ctypes.c_void_p(library.fmi2Instantiate(b"controller", 1, guid, b"", None, 0, 0))
        assert c.value
        assert library.fmi2SetupExperiment(c, 0, ctypes.c_double(0.0), ctypes.c_double(0.0),
                                           0, ctypes.c_double(0.0)) == FMI2_OK
        assert library.fmi2EnterInitializationMode(c) == FMI2_OK
        assert library.fmi2SetString(c, kind_vr, ctypes.c_size_t(1), kind) == FMI2_OK
        assert library.fmi2SetReal(c, vr, ctypes.c_size_t(2), values) == FMI2_OK
        assert library.fmi2ExitInitializationMode(c) == FMI2_OK
        assert library.fmi2DoStep(c, ctypes.c_double(0.0), ctypes.c_double(T), 1) == FMI2_OK
        state = ctypes.c_void_p()
        assert library.fmi2GetFMUstate(c, ctypes.byref(state)) == FMI2_OK
        assert library.fmi2FreeFMUstate(c, ctypes.byref(state)) == FMI2_OK
        assert library.fmi2Terminate(c) == FMI2_OK
        library.fmi2FreeInstance(c)

    grown = plant_tests.rss_growth(cycle)
    report("RSS growth over 10,000 instantiate/initialize/step/state/free cycles (bytes)",
           grown)
    assert grown < 1 << 20


# --- the master steps the C controller ---------------------------------------------------------

def test_a_battery_gives_the_same_results_with_either_controller_build(
        friction_plant_fmu: Path, pulse_controller_fmu: Path, tmp_path: Path) -> None:
    """scenarios/realism.toml at one target and seed (its eight cases; pwc, papwc and pid in C
    or in Python, exact in Python): results.csv, runs.csv and pulses.csv byte for byte."""
    from papwc.battery import load_battery, run_battery

    text = (PROJECT_DIR / "scenarios" / "realism.toml").read_text()
    lines = [('"maneuver.x_ref" = [1e-3]' if line.startswith('"maneuver.x_ref"') else
              '"plant.seed" = [2]' if line.startswith('"plant.seed"') else line)
             for line in text.splitlines()]
    battery_file = tmp_path / "realism_small.toml"
    battery_file.write_text("\n".join(lines) + "\n")
    battery = load_battery(battery_file)
    outcomes = {}
    for build, fmu in (("native", pulse_controller_fmu), ("python", None)):
        outcomes[build] = run_battery([battery], tmp_path / build, friction_plant_fmu,
                                      workers=1, progress=False, controller_fmu=fmu)
        assert outcomes[build].runs == 8 and not outcomes[build].failed
    for name in ("results.csv", "runs.csv", "pulses.csv"):
        native = (tmp_path / "native" / name).read_bytes()
        assert native == (tmp_path / "python" / name).read_bytes(), name
    report("realism (1 mm, seed 2): run time native / python controllers",
           f"{outcomes['native'].run_seconds:.1f} s / {outcomes['python'].run_seconds:.1f} s")


def test_the_master_steps_the_c_controller_only_for_its_kinds(pulse_controller_fmu: Path) -> None:
    from papwc.master.native_controller import (
        NativeControllerSlave,
        controller_slave,
        fmu_controller_library,
    )
    from papwc.master.slave import ControllerSlave

    library = fmu_controller_library(pulse_controller_fmu)
    assert library is not None
    for kind in ("pwc", "papwc", "pid"):
        assert isinstance(controller_slave(ControllerSettings(kind=kind), T, library),
                          NativeControllerSlave)
    for kind in ("exact", "dual_loop", "hybrid"):
        assert isinstance(controller_slave(ControllerSettings(kind=kind), T, library),
                          ControllerSlave)
    assert isinstance(controller_slave(ControllerSettings(), T, None), ControllerSlave)
    assert fmu_controller_library(pulse_controller_fmu.with_name("missing.fmu")) is None


@pytest.mark.parametrize(("kind", "fmu_name"), [("pid", "PulseController"),
                                             ("hybrid", "PulseControllerPython")])
def test_closed_loop_ssp_takes_the_controller_fmu_that_has_the_kind(
        friction_plant_fmu: Path, pulse_controller_fmu: Path, tmp_path: Path, kind: str,
        fmu_name: str) -> None:
    """ClosedLoop.ssp of realism_1khz.toml's PID (native) and of the hybrid in its place
    (kind_code 6, PulseControllerPython.fmu only): the controller component is the FMU
    that has the kind, and only that one is in the archive."""
    from papwc.fmubuild.ssp_writer import build_closed_loop_ssp

    text = (PROJECT_DIR / "scenarios" / "realism_1khz.toml").read_text()
    scenario = tmp_path / f"{kind}.toml"
    scenario.write_text(text[:text.index("[cases]")].replace('kind = "pid"', f'kind = "{kind}"'))
    ssp = build_closed_loop_ssp(tmp_path / "ssp", scenario, friction_plant_fmu,
                                pulse_controller_fmu)
    import xml.etree.ElementTree as ET

    with zipfile.ZipFile(ssp) as archive:
        ssd = ET.fromstring(archive.read("SystemStructure.ssd"))
        fmus = sorted(n for n in archive.namelist() if n.endswith(".fmu"))
    sources = {c.get("name"): c.get("source") for c in ssd.iter()
               if c.tag.endswith("}Component")}
    assert sources == {"plant": "resources/FrictionPlant.fmu",
                       "controller": f"resources/{fmu_name}.fmu"}
    assert fmus == sorted(["resources/FrictionPlant.fmu", f"resources/{fmu_name}.fmu"])


# --- the library a drive links: the example of the docs -----------------------------------------

@pytest.mark.parametrize("toolchain", ["cc", "zig"])
def test_the_example_runs_the_papers_scenario_as_the_python_master(
        tmp_path: Path, toolchain: str) -> None:
    """fmu_src/PulseController/example/paper_scenario.c (docs/_incoming/45-c-controller.md
    includes it) compiled by the system cc and by zig cc, both C99 with -Wall -Wextra
    -Werror: its ten maneuvers (final position and error, pulses, outcome, reason) are
    the Python master's run of scenarios/paper.toml's PAPWC (t_p_max = 0.03 s) on the
    in-process plant, to the last bit (%.17g reads back exactly)."""
    from papwc.fmubuild.native_tables import write_controller_header, write_plant_header
    from papwc.master import PhysicsSlave, run_controller
    from papwc.scenario import load_scenario

    if toolchain == "cc":
        command = [_cc()]
    else:
        from papwc.fmubuild.native_build import zig_command

        command = [*zig_command(), "-target", "x86_64-linux-gnu.2.17"]
    write_controller_header(tmp_path)
    write_plant_header(tmp_path)
    src = PROJECT_DIR / "fmu_src"
    program = tmp_path / "paper_scenario"
    done = subprocess.run([*command, "-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra",
                           "-Werror", "-I", str(tmp_path), "-I", str(src / "PulseController"),
                           "-I", str(src / "FrictionPlant"), "-o", str(program),
                           str(src / "PulseController" / "example" / "paper_scenario.c"),
                           str(src / "PulseController" / "controller.c"),
                           str(src / "FrictionPlant" / "plant.c"), "-lm"],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "ZIG_GLOBAL_CACHE_DIR": str(
                              Path(tempfile.gettempdir()) / "papwc-zig-cache")}, check=False)
    assert done.returncode == 0, done.stderr
    run = subprocess.run([str(program)], capture_output=True, text=True, timeout=120,
                         env={"PATH": "/usr/bin:/bin"}, check=False)
    assert run.returncode == 0, run.stderr
    got = [line.split() for line in run.stdout.splitlines()]
    paper = load_scenario(PROJECT_DIR / "scenarios" / "paper.toml")
    settings = paper.controllers[2]
    assert settings.kind == "papwc" and settings.t_p_max == 0.03
    plant = PhysicsSlave()
    plant.set_start_values(paper.plant)
    result = run_controller(plant, settings, paper.maneuver)
    assert not result.error and len(result.traces) == len(got) == 10
    for fields, trace in zip(got, result.traces, strict=True):
        x = trace.column("x")[-1]
        assert (int(fields[0]), float(fields[1]), float(fields[2])) == (
            trace.iteration, x, paper.maneuver.x_ref - x)
        assert [int(f) for f in fields[3:]] == [trace.column(name)[-1] for name in
                                                ("pulses", "outcome", "outcome_reason")]
    assert got[-1][4] == "1"  # settled, within the tolerance



# --- papwc bench's sections of the C controller -------------------------------------------------

def test_the_bench_sections_measure_what_they_name(fmu_dir: Path) -> None:
    """The sections run (quick) and give their rows; their figures are read by people from
    ``papwc bench``, not asserted here."""
    from papwc.bench import BenchContext
    from papwc.bench.native_controller import native_closed_loop, realism_input, worst_update

    text, runs = realism_input((1,))
    assert runs == 8 * 3 * 3 and text.count("\nend\n") + text.startswith("end") == runs
    context = BenchContext(fmu_dir=fmu_dir, quick=True)
    rows = {r.label: r for r in worst_update(context)}
    assert 0.0 < rows["longest update"].value and rows["mean update"].value > 0.0
    assert "72 runs" in context.notes[0] and "43200 updates" in context.notes[0]
    context.notes.clear()
    rows = {r.label: r for r in native_closed_loop(context)}
    assert rows["closed-loop step, both native FMUs"].value > 0.0
    assert any(label.startswith("goal: ratio at most") for label in rows)


# --- the pythonfmu build in a host with no Python --------------------------------------------

@pytest.fixture(scope="module")
def c_host(tmp_path_factory) -> Path:
    """tests/c_host/fmu_host.c compiled with the system cc."""
    import fmpy

    host = tmp_path_factory.mktemp("host") / "fmu_host"
    done = subprocess.run([_cc(), "-std=c99", "-O2", "-Wall", "-I",
                           str(Path(fmpy.__file__).parent / "c-code"), "-o", str(host),
                           str(PROJECT_DIR / "tests" / "c_host" / "fmu_host.c"), "-ldl"],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    return host


def _python_fmu_run(c_host: Path, unzipped: Path, env: dict[str, str], steps: int = 5
                    ) -> subprocess.CompletedProcess:
    """PulseControllerPython.fmu's exact kind (kind_code 3) in the C host, x_ref 1 mm, the
    reading 0 at every step; u and pulses per step."""
    md = read_model_description(str(unzipped))
    variables = {v.name: v.valueReference for v in md.modelVariables}
    binary_path = unzipped / "binaries" / "linux64" / "PulseControllerPython.so"
    return subprocess.run(
        [str(c_host), str(binary_path), md.guid, repr(T), f"i:{variables['kind_code']}=3",
         f"r:{variables['x_ref_offset']}=0.001", "--", f"{variables['u']}r",
         f"{variables['pulses']}i"], input=f"{variables['x_meas']} 0.0\n" * steps,
        capture_output=True, text=True, timeout=120, env=env, check=False)


def test_the_pythonfmu_build_refuses_in_one_line_where_the_host_has_no_python(
        c_host: Path, pulse_controller_python_unzipped: Path) -> None:
    """A C host started with an empty environment: fmi2Instantiate returns NULL, one line
    on stderr names what is missing and the native FMU; the host ends normally (no crash)."""
    done = _python_fmu_run(c_host, pulse_controller_python_unzipped, {"PATH": "/usr/bin:/bin"})
    lines = [line for line in done.stderr.splitlines()
             if line.startswith("PulseControllerPython controller: fmi2Instantiate refused")]
    assert done.returncode == 3, (done.returncode, done.stderr)  # the host's "no instance"
    assert len(lines) == 1, done.stderr
    assert "this process has no Python loaded" in lines[0]
    assert "the native PulseController.fmu" in lines[0] and "LD_PRELOAD" in lines[0]
    report("pythonfmu build, C host with no Python", lines[0][:120] + " ...")


def test_the_pythonfmu_build_runs_in_a_c_host_with_libpython_preloaded(
        c_host: Path, pulse_controller_python_unzipped: Path) -> None:
    """The same host with LD_PRELOAD=libpython (``papwc hostenv``) and PATH=/usr/bin:/bin
    (whose python3 is not this interpreter: the loader gives Python its own home): the exact
    controller's forces, as the Python controller gives them."""
    from papwc.host_environment import libpython

    done = _python_fmu_run(c_host, pulse_controller_python_unzipped,
                           {"PATH": "/usr/bin:/bin", "LD_PRELOAD": str(libpython())})
    assert done.returncode == 0, done.stderr
    python = make_controller(ControllerSettings(kind="exact"), T)
    expected = []
    for k in range(5):
        u = python.update(k * T, 0.0, 0.001)
        expected.append([u, python.outputs()["pulses"]])
    got = [[float.fromhex(a), int(b)] for a, b in (line.split() for line in
                                                    done.stdout.splitlines())]
    assert got == expected and got[0][0] != 0.0


def test_papwc_run_gives_the_same_files_with_either_controller_build(tmp_path: Path) -> None:
    """papwc run --controllers native (the C controller, its FMU built into OUT/fmu) and
    --controllers python: every CSV the same bytes."""
    from harness import SHORT_PAPER

    scenario = tmp_path / "short.toml"
    scenario.write_text(SHORT_PAPER)
    for build in ("native", "python"):
        done = subprocess.run([sys.executable, "-m", "papwc.cli", "run", str(scenario), "--out",
                               str(tmp_path / build), "--plant", "physics", "--controllers",
                               build], capture_output=True, text=True, timeout=600, check=False)
        assert done.returncode == 0, done.stderr
    native = sorted(p.name for p in (tmp_path / "native").glob("*.csv"))
    assert native == sorted(p.name for p in (tmp_path / "python").glob("*.csv"))
    assert len(native) > 4 and (tmp_path / "native" / "fmu" / "PulseController.fmu").is_file()
    for name in native:
        assert (tmp_path / "native" / name).read_bytes() == \
            (tmp_path / "python" / name).read_bytes(), name


def test_fmpy_builds_the_controller_sources_into_a_working_binary(
        pulse_controller_fmu: Path, tmp_path: Path) -> None:
    """sources/ of PulseController.fmu built by fmpy's build_platform_binary (CMake, zig):
    the binary built closes the paper's PAPWC loop (two iterations, delayed timing) as the
    Python controller does, bit for bit."""
    import dataclasses

    from papwc.master import FmuSlave, PhysicsSlave, run_closed_loop, run_controller
    from papwc.scenario import load_scenario

    unzipped = plant_tests.build_sources(pulse_controller_fmu, tmp_path)
    paper = load_scenario(PROJECT_DIR / "scenarios" / "paper.toml")
    s = paper.controllers[2]
    maneuver = dataclasses.replace(paper.maneuver, iterations=2, timing="delayed")
    plant = PhysicsSlave()
    plant.set_start_values(paper.plant)
    with FmuSlave(pulse_controller_fmu, name="controller", unzip_dir=unzipped,
                  restart_input="maneuver") as controller:
        controller.set_start_values(settings_start_values(s, maneuver.T))
        built = run_closed_loop(plant, controller, maneuver, s)
    reference_plant = PhysicsSlave()
    reference_plant.set_start_values(paper.plant)
    reference = run_controller(reference_plant, s, maneuver)
    assert not built.error and not reference.error
    for a, b in zip(built.traces, reference.traces, strict=True):
        for name in ("x", "u", "pulses", "b_hat", "mode"):
            assert a.column(name) == b.column(name), name
    assert built.traces[0].column("pulses")[-1] > 3
