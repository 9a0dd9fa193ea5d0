"""The native FrictionPlant.fmu (C, built by zig for win64, linux64 and darwin64).

- the same physics as :class:`papwc.model.dynamics.Plant`, bit for bit, through fmpy, over
  random parameters, forces and step sizes, with FMU states got, set and serialized in the
  middle (hypothesis);
- every refusal returns fmi2Error (fmi2Discard for a non-finite input or a step size that
  is not > 0) and changes nothing; a wrong GUID gives no instance;
- the binaries: every fmi2 function exported by each; linux64 needs glibc <= 2.17 and no
  libstdc++/libgcc_s/libpython; win64 imports KERNEL32 and the C runtime only; darwin64 is
  one universal file of x86_64 and arm64 linking libSystem only;
- no Python in the host: ecos's command line runs it with no LD_PRELOAD and no Python on
  PATH, fmpy runs it in a process where pythonfmu cannot be imported;
- ``sources/`` builds with fmpy's ``build_platform_binary`` (CMake, zig as the compiler);
- 10,000 instantiate/initialize/step/free cycles grow the RSS by less than 1 MB.

Each test that measures prints its figure (``pytest -s``: lines ``native:``).
"""

from __future__ import annotations

import ctypes
import math
import os
import re
import shutil
import stat
import struct
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from harness import FmuInstance
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from papwc.master.native_plant import FpParams
from papwc.model.dynamics import Plant
from papwc.model.plant import PLANT_DEFAULTS

FMI2_OK, FMI2_DISCARD, FMI2_ERROR = 0, 2, 3
T = 0.01
#: Parameter sets: no deviation, each deviation, all that combine.
CASES = {
    "exact": {},
    "stribeck": {"v_s": 0.01, "delta_s": 1.5},
    "lugre": {"sigma_0": 1e7, "sigma_1": 2e4},
    "ripple": {"ripple": 0.2, "ripple_period": 2e-3, "ripple_phase": 0.3},
    "stiction": {"f_s_spread": 0.15, "seed": 7},
    "lag": {"tau_u": 0.004},
    "flexible": {"m_d": 30.0, "k_t": 2e6, "c_t": 300.0},
    "noise": {"noise_std": 2e-7, "x_resolution": 1e-7, "seed": 3},
    "all": {"v_s": 0.02, "ripple": 0.1, "f_s_spread": 0.1, "seed": 11, "tau_u": 0.003,
            "m_d": 40.0, "k_t": 3e6, "c_t": 200.0, "noise_std": 1e-7, "x_resolution": 1e-7},
}
OUTPUTS = ("x", "v", "x_meas")


def report(what: str, value: object) -> None:
    print(f"\nnative: {what}: {value}")


def fmi2_functions() -> list[str]:
    """Every function of FMI 2.0, as fmpy's copy of the standard's header declares them."""
    import fmpy

    header = (Path(fmpy.__file__).parent / "c-code" / "fmi2Functions.h").read_text()
    names = sorted(set(re.findall(r"FMI2_Export\s+\w+TYPE\s+(fmi2\w+);", header)))
    assert len(names) == 44, names
    return names


def outputs(fmu: FmuInstance) -> tuple:
    """x, v, x_meas of the plant FMU, and whether it is stuck."""
    return (*fmu.fmu.getReal([fmu.vars[n].valueReference for n in OUTPUTS]),
            fmu.fmu.getBoolean([fmu.vars["stuck"].valueReference])[0])


def plant_outputs(plant: Plant) -> tuple:
    return (plant.x, plant.v, plant.x_meas(), plant.v == 0.0)


# --- same physics ------------------------------------------------------------------------------

forces = st.lists(st.tuples(st.sampled_from([0.0, 300.0, -300.0, 120.0, 250.0, -180.0, 90.0]),
                            st.sampled_from([T, T, T, 0.002, 0.005, 0.013, 0.03])),
                  min_size=4, max_size=40)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(case=st.sampled_from(sorted(CASES)), seq=forces, cut=st.integers(0, 39),
       m=st.sampled_from([150.0, 90.0]))
def test_the_native_fmu_is_the_model_layer_bit_for_bit(friction_plant_unzipped: Path, case: str,
                                                       seq, cut: int, m: float) -> None:
    params = {**CASES[case], "m": m}
    plant = Plant({**PLANT_DEFAULTS, **params})
    fmu = FmuInstance(friction_plant_unzipped, "plant")
    other = FmuInstance(friction_plant_unzipped, "other")
    try:
        fmu.init(**params)
        other.init(**params)
        assert outputs(fmu) == plant_outputs(plant)
        cut = min(cut, len(seq) - 1)
        saved = None
        for k, (u, h) in enumerate(seq):
            if k == cut:  # the state got, serialized and set in the middle of the run
                saved = fmu.fmu.getFMUstate()
                data = fmu.fmu.serializeFMUstate(saved)
                restored = other.fmu.deSerializeFMUstate(data)
                other.fmu.setFMUstate(restored)
                other.fmu.freeFMUstate(restored)
                other.t = fmu.t
                t_saved, expected = fmu.t, []
            fmu.advance(h, u=u)
            assert plant.step(u, h) is None
            assert outputs(fmu) == plant_outputs(plant), (case, k)
            if saved is not None:
                expected.append(outputs(fmu))
                other.advance(h, u=u)
                assert outputs(other) == expected[-1]
        fmu.fmu.setFMUstate(saved)  # back to the middle: the same steps again
        fmu.fmu.freeFMUstate(saved)
        fmu.t = t_saved
        for (u, h), then in zip(seq[cut:], expected, strict=True):
            fmu.advance(h, u=u)
            assert outputs(fmu) == then
        assert not [m for m in fmu.messages + other.messages if m.status >= FMI2_DISCARD]
    finally:
        fmu.close()
        other.close()


def test_fmi2_reset_gives_the_same_run_again(friction_plant_unzipped: Path) -> None:
    fmu = FmuInstance(friction_plant_unzipped, "plant")
    runs = []
    for _ in range(3):
        fmu.init(**CASES["all"])
        for k in range(60):
            fmu.advance(T, u=300.0 if k < 6 else 0.0)
        runs.append(outputs(fmu))
        fmu.fmu.terminate()
        fmu.fmu.reset()
    fmu.close(terminate=False)
    assert runs[0] == runs[1] == runs[2] and runs[0][0] > 1e-4


# --- refusals ----------------------------------------------------------------------------------


def refused(call) -> int:
    """The status of a call expected to be refused (fmpy raises for any status but OK)."""
    with pytest.raises(FMICallException) as info:
        call()
    return info.value.status


@pytest.mark.parametrize("logging", [True, False])
def test_each_refusal_is_an_error_or_a_discard_never_ok(friction_plant_unzipped: Path,
                                                        logging: bool) -> None:
    fmu = FmuInstance(friction_plant_unzipped, "plant", logging=logging)
    vr = {name: v.valueReference for name, v in fmu.vars.items()}
    assert refused(lambda: fmu.fmu.doStep(0.0, T)) == FMI2_ERROR  # before initialization
    fmu.fmu.setupExperiment(startTime=0.0)
    fmu.fmu.enterInitializationMode()
    fmu.set("f_s", 50.0)  # below f_c: a rule between parameters
    assert refused(fmu.fmu.exitInitializationMode) == FMI2_ERROR
    fmu.set("m", -1.0)  # out of its range (the instance stays in initialization mode)
    assert refused(fmu.fmu.exitInitializationMode) == FMI2_ERROR
    fmu.set("m", 150.0)
    fmu.set("f_s", 130.0)
    fmu.fmu.exitInitializationMode()  # corrected: accepted
    fmu.advance(T, u=300.0)
    x = outputs(fmu)
    cases = {
        "parameter after initialization": lambda: fmu.fmu.setReal([vr["m"]], [300.0]),
        "output set": lambda: fmu.fmu.setReal([vr["x"]], [1.0]),
        "no such variable": lambda: fmu.fmu.getReal([999]),
        "wrong type": lambda: fmu.fmu.getInteger([vr["m"]]),
        "a String": lambda: fmu.fmu.getString([0]),
        "communication point that jumps": lambda: fmu.fmu.doStep(fmu.t + 0.5, T),
        "setup after initialization": lambda: fmu.fmu.setupExperiment(startTime=0.0),
        "directional derivative": lambda: fmu.fmu.getDirectionalDerivative([vr["x"]],
                                                                           [vr["u"]], [1.0]),
    }
    for what, call in cases.items():
        assert refused(call) == FMI2_ERROR, what
    set_time = fmu.fmu.dll.fmi2SetTime  # Model Exchange: exported, refused
    set_time.argtypes = [ctypes.c_void_p, ctypes.c_double]
    assert set_time(fmu.fmu.component, 0.0) == FMI2_ERROR
    assert fmu.fmu.getReal([vr["m"]]) == [150.0]  # the refused value was not taken
    for h in (0.0, -T, math.inf, math.nan):
        assert refused(lambda h=h: fmu.fmu.doStep(fmu.t, h)) == FMI2_DISCARD, h
    fmu.fmu.setReal([vr["u"]], [math.nan])
    assert refused(lambda: fmu.fmu.doStep(fmu.t, T)) == FMI2_DISCARD
    assert outputs(fmu) == x  # every refusal left the state as it was
    fmu.advance(T, u=0.0)  # and the instance steps on
    state = fmu.fmu.getFMUstate()
    data = bytes(fmu.fmu.serializeFMUstate(state))
    fmu.fmu.freeFMUstate(state)
    guid_at = data.index(b"{")
    bad_states = {
        "truncated": data[:-1],
        "longer": data + b"\0",
        "garbage": bytes(len(data)),
        "another FMU's": data[:guid_at + 1] + b"0" + data[guid_at + 2:],
    }
    # the model data follows the marker (8 bytes), the GUID (64) and the phase and time (16):
    # first the parameters (FpParams, m first), then the plant's state (FpState, x first)
    m_at = 8 + 64 + 16  # after the header: m is FpParams' first field, the state follows it
    x_at = m_at + ctypes.sizeof(FpParams)
    assert struct.unpack_from("<d", data, m_at) == (150.0,)
    assert struct.unpack_from("<d", data, x_at) == (outputs(fmu)[0],)
    bad_states["invalid parameter m = -1"] = (data[:m_at] + struct.pack("<d", -1.0)
                                              + data[m_at + 8:])
    bad_states["position not finite"] = (data[:x_at] + struct.pack("<d", math.nan)
                                         + data[x_at + 8:])
    for what, bad in bad_states.items():
        assert refused(lambda bad=bad: fmu.fmu.deSerializeFMUstate(bad)) == FMI2_ERROR, what
    fmu.fmu.terminate()
    assert refused(lambda: fmu.fmu.doStep(fmu.t, T)) == FMI2_ERROR
    assert refused(lambda: fmu.fmu.setReal([vr["u"]], [1.0])) == FMI2_ERROR
    if logging:
        errors = fmu.logged(FMI2_ERROR)
        assert any("parameter f_s = 50.0 N: must be >= f_c = 100.0 N" in m for m in errors)
        assert any("parameter m = -1.0 kg: must satisfy 1e-06 <= m <= 1e+09 kg" in m
                   for m in errors)
        assert any("parameter m cannot be set after initialization: 300.0 refused, it stays "
                   "150.0" in m for m in errors)
        assert any("input u = nan N is not finite" in m for m in fmu.logged(FMI2_DISCARD))
        assert any("its parameters are invalid: parameter m = -1.0 kg" in m for m in errors)
        assert any("the state does not fit" in m and "nan" in m for m in errors)
    else:
        assert fmu.messages == []
    fmu.close(terminate=False)


def test_a_wrong_guid_gives_no_instance(friction_plant_unzipped: Path) -> None:
    with pytest.raises(Exception, match="Failed to instantiate"):
        FmuInstance(friction_plant_unzipped, "plant", guid="{00000000-0000-0000-0000-000000000000}")


# --- the binaries ------------------------------------------------------------------------------


def _elf_needs(data: bytes) -> tuple[list[str], set[str]]:
    """DT_NEEDED libraries and the GLIBC_* versions named in an ELF64 shared object."""
    assert data[:4] == b"\x7fELF" and data[4] == 2  # 64-bit
    e_shoff, = struct.unpack_from("<Q", data, 0x28)
    e_shentsize, e_shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, e_shoff + i * e_shentsize)
                for i in range(e_shnum)]
    dynamic = next(s for s in sections if s[1] == 6)  # SHT_DYNAMIC
    dynstr = sections[dynamic[6]]  # sh_link
    strings = data[dynstr[4]:dynstr[4] + dynstr[5]]
    needed = []
    for off in range(dynamic[4], dynamic[4] + dynamic[5], 16):
        tag, value = struct.unpack_from("<qQ", data, off)
        if tag == 1:  # DT_NEEDED
            needed.append(strings[value:strings.index(b"\0", value)].decode())
    versions = set(re.findall(rb"GLIBC_[0-9.]+", strings))
    return needed, {v.decode() for v in versions}


def _macho_thin(data: bytes, offset: int) -> tuple[int, list[str], set[str]]:
    """CPU type, linked dylibs and exported symbols of a 64-bit Mach-O at ``offset``."""
    magic, cputype, _, _, ncmds, _, _, _ = struct.unpack_from("<IiiIIIII", data, offset)
    assert magic == 0xFEEDFACF
    pos, dylibs, exported = offset + 32, [], set()
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, pos)
        if cmd in (0xC, 0x80000018):  # LC_LOAD_DYLIB, LC_LOAD_WEAK_DYLIB
            name_at, = struct.unpack_from("<I", data, pos + 8)
            dylibs.append(data[pos + name_at:data.index(b"\0", pos + name_at)].decode())
        if cmd == 0x2:  # LC_SYMTAB
            symoff, nsyms, stroff, _ = struct.unpack_from("<IIII", data, pos + 8)
            for i in range(nsyms):
                strx, n_type = struct.unpack_from("<IB", data, offset + symoff + 16 * i)
                if n_type & 0x01 and n_type & 0x0E == 0x0E:  # N_EXT, N_SECT
                    start = offset + stroff + strx
                    exported.add(data[start:data.index(b"\0", start)].decode())
        pos += size
    return cputype, dylibs, exported


def _binary(fmu: Path, platform: str, suffix: str) -> bytes:
    with zipfile.ZipFile(fmu) as archive:
        return archive.read(f"binaries/{platform}/FrictionPlant{suffix}")


def test_the_linux_binary_needs_glibc_2_17_and_nothing_of_python_or_cxx(
        friction_plant_fmu: Path, friction_plant_unzipped: Path) -> None:
    needed, versions = _elf_needs(_binary(friction_plant_fmu, "linux64", ".so"))
    newest = max(tuple(int(p) for p in v.split("_")[1].split(".")) for v in versions)
    report("linux64 DT_NEEDED", needed)
    report("linux64 newest glibc symbol version", ".".join(map(str, newest)))
    assert newest <= (2, 17)
    assert set(needed) <= {"libc.so.6", "libm.so.6"}
    library = ctypes.CDLL(str(friction_plant_unzipped / "binaries" / "linux64" /
                              "FrictionPlant.so"))
    missing = [f for f in fmi2_functions() if not hasattr(library, f)]
    assert missing == []


def test_the_windows_binary_imports_only_the_system_runtime(friction_plant_fmu: Path) -> None:
    pefile = pytest.importorskip("pefile")
    pe = pefile.PE(data=_binary(friction_plant_fmu, "win64", ".dll"))
    assert pe.FILE_HEADER.Machine == 0x8664  # AMD64
    dlls = sorted(entry.dll.decode() for entry in pe.DIRECTORY_ENTRY_IMPORT)
    report("win64 imports", dlls)
    for dll in dlls:
        name = dll.lower()
        assert name in ("kernel32.dll", "msvcrt.dll", "ucrtbase.dll") or name.startswith(
            "api-ms-win-crt-"), dll
        assert "python" not in name
    exported = {e.name.decode() for e in pe.DIRECTORY_ENTRY_EXPORT.symbols if e.name}
    assert set(fmi2_functions()) <= exported


def test_the_macos_binary_is_universal_and_links_libsystem_only(friction_plant_fmu: Path) -> None:
    data = _binary(friction_plant_fmu, "darwin64", ".dylib")
    magic, count = struct.unpack_from(">II", data, 0)
    assert magic == 0xCAFEBABE and count == 2
    cpus = {}
    for i in range(count):
        cputype, _, offset, size, _ = struct.unpack_from(">iiIII", data, 8 + 20 * i)
        thin_cpu, dylibs, exported = _macho_thin(data, offset)
        assert thin_cpu == cputype and offset + size <= len(data)
        cpus[cputype] = dylibs
        assert dylibs == ["/usr/lib/libSystem.B.dylib"], dylibs
        assert {"_" + f for f in fmi2_functions()} <= exported
    report("darwin64 architectures (CPU types)", sorted(hex(c) for c in cpus))
    assert set(cpus) == {0x01000007, 0x0100000C}  # x86_64, arm64


def test_the_archive_holds_sources_documentation_and_licenses(friction_plant_fmu: Path) -> None:
    with zipfile.ZipFile(friction_plant_fmu) as archive:
        names = set(archive.namelist())
        index = archive.read("documentation/index.html").decode()
        md = archive.read("modelDescription.xml").decode()
    for name in ("sources/fmi2_cs.c", "sources/fmu_model.c", "sources/plant.c",
                 "sources/plant_vars.h", "sources/fmu_config.h", "sources/fmi2Functions.h",
                 "documentation/reference.png", "licenses/LICENSE.txt"):
        assert name in names, name
    assert not any(n.startswith("resources/") for n in names)  # no Python bundled
    for c_file in sorted(n for n in names if n.startswith("sources/") and n.endswith(".c")):
        assert f'<File name="{c_file.split("/")[1]}"' in md
    assert "m * dv/dt = u - f_c * sgn(v) - c * v" in index
    assert "<code>x_resolution</code>" in index and "0 &lt;= x_resolution &lt;= 1 m" in index


# --- hosts without Python ----------------------------------------------------------------------


def test_fmpy_runs_it_where_pythonfmu_cannot_be_imported(friction_plant_fmu: Path) -> None:
    code = textwrap.dedent(f"""
        import sys
        sys.modules["pythonfmu"] = None  # importing pythonfmu now raises ImportError
        try:
            import pythonfmu  # noqa: F401
            raise SystemExit("pythonfmu is importable")
        except ImportError:
            pass
        import numpy as np
        from fmpy import simulate_fmu
        u = np.array([(0.0, 300.0), (0.05, 300.0), (0.05, 0.0), (1.0, 0.0)],
                     dtype=[("time", np.float64), ("u", np.float64)])
        r = simulate_fmu({str(friction_plant_fmu)!r}, input=u, output_interval=0.01,
                         stop_time=0.3, output=["x"])
        print(repr(float(r["x"][-1])))
        print("pythonfmu" in sys.modules and sys.modules["pythonfmu"] is not None)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    x_end, loaded = done.stdout.split()
    import numpy as np
    from fmpy import simulate_fmu

    u = np.array([(0.0, 300.0), (0.05, 300.0), (0.05, 0.0), (1.0, 0.0)],
                 dtype=[("time", np.float64), ("u", np.float64)])
    here = simulate_fmu(str(friction_plant_fmu), input=u, output_interval=0.01, stop_time=0.3,
                        output=["x"])
    assert float(x_end) == float(here["x"][-1]) > 1e-3 and loaded == "False"


@pytest.fixture(scope="module")
def ecos_binary(tmp_path_factory) -> Path:
    try:
        import ecospy
    except (ImportError, OSError) as exc:
        if os.environ.get("CI") == "true":
            pytest.fail(f"ecos is required in CI: {exc}")
        pytest.skip(f"ecospy cannot be imported: {exc}")
    source = Path(ecospy.__file__).parent / "binaries" / "ecos"
    folder = tmp_path_factory.mktemp("ecosbin")
    binary = folder / "ecos"
    shutil.copy(source, binary)
    binary.chmod(binary.stat().st_mode | stat.S_IXUSR)
    return binary


def test_ecos_command_line_runs_it_without_python(ecos_binary: Path, friction_plant_fmu: Path,
                                                  tmp_path: Path) -> None:
    """ecos simulate with no LD_PRELOAD and a PATH holding only the tools ecos calls (unzip,
    chmod): the position, carried at all its digits into a second plant's input (ecos's
    CSV writes 6 decimals), matches fmpy to 1e-12 m."""
    sys.path.insert(0, str(Path(__file__).parent))
    import test_fmi_hosts as hosts

    ssp = tmp_path / "Pulse.ssp"
    hosts.plant_ssp(friction_plant_fmu, tmp_path / "plain.ssp")
    with zipfile.ZipFile(tmp_path / "plain.ssp") as src:
        members = {name: src.read(name) for name in src.namelist()}
    ssd = members["SystemStructure.ssd"].decode()
    sink = ('<ssd:Component name="sink" type="application/x-fmu-sharedlibrary" '
            'source="resources/FrictionPlant.fmu"><ssd:Connectors><ssd:Connector name="u" '
            'kind="input"><ssc:Real/></ssd:Connector></ssd:Connectors></ssd:Component>')
    ssd = ssd.replace("</ssd:Elements>", sink + "</ssd:Elements>")
    ssd = ssd.replace("<ssd:Connections/>", (
        '<ssd:Connections><ssd:Connection startElement="plant" startConnector="x" '
        f'endElement="sink" endConnector="u"><ssc:LinearTransformation factor="{hosts.SCALE!r}" '
        'offset="0.0"/></ssd:Connection></ssd:Connections>'))
    members["SystemStructure.ssd"] = ssd.encode()
    with zipfile.ZipFile(ssp, "w") as dst:
        for name, data in members.items():
            dst.writestr(name, data)
    scenario = tmp_path / "pulse.xml"
    scenario.write_text(
        '<ecos:Scenario xmlns:ecos="http://github.com/Ecos-platform/libecos/resources/schema/'
        'ScenarioConfig" name="pulse" eps="1e-6">'
        f'<ecos:action t="0"><ecos:variable id="plant::u"><ecos:real value="{hosts.PULSE_U!r}"/>'
        '</ecos:variable></ecos:action>'
        f'<ecos:action t="{hosts.PULSE_END!r}"><ecos:variable id="plant::u">'
        '<ecos:real value="0.0"/></ecos:variable></ecos:action></ecos:Scenario>')
    tools = tmp_path / "tools"
    tools.mkdir()
    for tool in ("unzip", "chmod"):
        found = shutil.which(tool)
        if found is None and os.environ.get("CI") == "true":
            pytest.fail(f"ecos calls {tool}: .ci/run installs it")
        if found is None:
            pytest.skip(f"ecos calls {tool}, which is not installed")
        (tools / tool).symlink_to(found)
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONHOME",
                                                             "PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = str(tools)
    assert shutil.which("python3", path=env["PATH"]) is None
    assert shutil.which("python", path=env["PATH"]) is None
    run = tmp_path / "run"
    run.mkdir()
    done = subprocess.run([str(ecos_binary), "simulate", "--path", str(ssp), "--stepSize",
                           repr(hosts.STEP), "--stopTime", repr(hosts.STOP), "--parameterSet",
                           "params", "--scenarioConfig", str(scenario), "-l", "warn"],
                          cwd=run, env=env, capture_output=True, text=True, timeout=300,
                          check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    (path,) = run.glob("*.csv")
    rows = hosts.read_csv(path)
    xs = [float(r["sink::u[REAL]"]) / hosts.SCALE for r in rows]
    reference = hosts.fmpy_pulse_x(friction_plant_fmu)
    error = hosts.max_error(xs, reference)
    report("ecos command line without Python, max |x - x_fmpy| (m)", error)
    assert len(xs) >= len(reference) - 1 and error <= hosts.TOL_X
    assert xs[-1] > hosts.PLANT["x0"] + 1e-3


def build_sources(fmu: Path, tmp_path: Path) -> Path:
    """The FMU extracted into ``tmp_path``, its linux64 binary built anew from ``sources/`` by
    fmpy's build_platform_binary (CMake, zig as the C compiler, CFLAGS=-ffp-contract=off);
    the folder. Skips where cmake or make is missing (fails in CI)."""
    beside = Path(sys.executable).parent  # pip's cmake (the test extra) in this environment
    cmake = shutil.which("cmake") or shutil.which("cmake", path=str(beside))
    if cmake is None:
        if os.environ.get("CI") == "true":
            pytest.fail("cmake is required in CI (pip install -e '.[test]' installs it)")
        pytest.skip("cmake is not installed")
    if shutil.which("make") is None:  # CMake's default generator on Linux
        pytest.skip("make is not installed (CMake's Unix Makefiles generator needs it)")
    from fmpy import extract
    from fmpy.build import build_platform_binary

    unzipped = Path(extract(str(fmu), str(tmp_path / "fmu")))
    shipped = unzipped / "binaries" / "linux64" / f"{fmu.stem}.so"
    shipped.unlink()
    compiler = tmp_path / "zigcc"
    compiler.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m ziglang cc "$@"\n')
    compiler.chmod(0o755)
    env = dict(os.environ, CC=str(compiler), CFLAGS="-ffp-contract=off",
               PATH=str(Path(cmake).parent) + os.pathsep + os.environ.get("PATH", ""))
    old = os.environ.copy()
    os.environ.update(env)
    (tmp_path / "build").mkdir()
    try:
        build_platform_binary(unzipped, tmp_path / "build")
    finally:
        os.environ.clear()
        os.environ.update(old)
    assert shipped.is_file()
    return unzipped


@pytest.mark.slow
def test_fmpy_builds_the_sources_into_a_working_binary(friction_plant_fmu: Path,
                                                       tmp_path: Path) -> None:
    """fmpy's build_platform_binary (CMake) compiles sources/ (zig as the C compiler); with
    the flags the sources ask for (CFLAGS=-ffp-contract=off: no fused multiply-adds), the
    binary built gives the shipped one's trajectory bit for bit."""
    unzipped = build_sources(friction_plant_fmu, tmp_path)
    from fmpy import simulate_fmu

    signal = [(0.0, 300.0), (0.05, 300.0), (0.05, 0.0), (1.0, 0.0)]
    import numpy as np

    u = np.array(signal, dtype=[("time", np.float64), ("u", np.float64)])
    built = simulate_fmu(str(unzipped), input=u, output_interval=T, stop_time=0.3,
                         output=["x", "v"])
    original = simulate_fmu(str(friction_plant_fmu), input=u, output_interval=T,
                            stop_time=0.3, output=["x", "v"])
    assert built["x"].tolist() == original["x"].tolist()


# --- memory ------------------------------------------------------------------------------------


def _rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def fmi_library(unzipped: Path) -> ctypes.CDLL:
    """The linux64 binary of an extracted FMU, fmi2Instantiate typed."""
    md = read_model_description(str(unzipped))
    library = ctypes.CDLL(str(unzipped / "binaries" / "linux64" /
                              f"{md.coSimulation.modelIdentifier}.so"))
    library.fmi2Instantiate.restype = ctypes.c_void_p
    library.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                                        ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int,
                                        ctypes.c_int]
    return library


def rss_growth(cycle, n: int = 10_000) -> int:
    """Bytes the RSS grows by over ``n`` calls of ``cycle`` (after 500 that let the
    allocator's pools settle)."""
    for _ in range(500):
        cycle()
    before = _rss()
    for _ in range(n):
        cycle()
    return _rss() - before


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/statm").is_file(), reason="needs /proc (Linux)")
def test_ten_thousand_instances_do_not_grow_the_memory(friction_plant_unzipped: Path) -> None:
    md = read_model_description(str(friction_plant_unzipped))
    library = fmi_library(friction_plant_unzipped)
    for name in ("fmi2SetupExperiment", "fmi2EnterInitializationMode",
                 "fmi2ExitInitializationMode", "fmi2DoStep", "fmi2Terminate",
                 "fmi2FreeInstance", "fmi2SetReal", "fmi2GetFMUstate", "fmi2FreeFMUstate"):
        getattr(library, name).argtypes = None
    guid = md.guid.encode()
    vr = (ctypes.c_uint * 1)(*[v.valueReference for v in md.modelVariables if v.name == "u"])
    u = (ctypes.c_double * 1)(300.0)

    def cycle() -> None:
        c = ctypes.c_void_p(library.fmi2Instantiate(b"plant", 1, guid, b"", None, 0, 0))
        assert c.value
        assert library.fmi2SetupExperiment(c, 0, ctypes.c_double(0.0), ctypes.c_double(0.0),
                                           0, ctypes.c_double(0.0)) == FMI2_OK
        assert library.fmi2EnterInitializationMode(c) == FMI2_OK
        assert library.fmi2ExitInitializationMode(c) == FMI2_OK
        assert library.fmi2SetReal(c, vr, ctypes.c_size_t(1), u) == FMI2_OK
        assert library.fmi2DoStep(c, ctypes.c_double(0.0), ctypes.c_double(T), 1) == FMI2_OK
        state = ctypes.c_void_p()
        assert library.fmi2GetFMUstate(c, ctypes.byref(state)) == FMI2_OK
        assert library.fmi2FreeFMUstate(c, ctypes.byref(state)) == FMI2_OK
        assert library.fmi2Terminate(c) == FMI2_OK
        library.fmi2FreeInstance(c)

    grown = rss_growth(cycle)
    report("RSS growth over 10,000 instantiate/initialize/step/state/free cycles (bytes)",
           grown)
    assert grown < 1 << 20


# --- the pythonfmu plant on an older Python ---------------------------------------------------


def test_the_pythonfmu_bundle_refuses_python_older_than_3_10(pythonfmu_plant_fmu: Path,
                                                             tmp_path: Path) -> None:
    def runs(python: str | None) -> bool:
        return python is not None and Path(python).is_file() and subprocess.run(
            [python, "-c", "import sys; assert sys.version_info < (3, 10)"],
            capture_output=True, timeout=60, check=False).returncode == 0

    pyenv = Path.home() / ".pyenv" / "versions"
    candidates = [shutil.which("python3.9"), shutil.which("python3.8"),
                  *sorted(str(p / "bin" / "python") for p in pyenv.glob("3.[89].*"))]
    old = next((p for p in candidates if runs(p)), None)
    if old is None:
        pytest.skip("no Python 3.8 or 3.9 installed")
    with zipfile.ZipFile(pythonfmu_plant_fmu) as archive:
        archive.extractall(tmp_path)
    done = subprocess.run([old, "-c", "import papwc_friction_plant"], cwd=tmp_path / "resources",
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode != 0
    assert ("FrictionPlant.fmu (pythonfmu) needs Python 3.10 or newer in the host; this host "
            "runs Python 3.") in done.stderr


# --- a battery worker reuses its plant ---------------------------------------------------------


@pytest.mark.slow
def test_a_worker_reuses_one_plant_instance_with_the_results_of_fresh_ones(
        friction_plant_fmu: Path, friction_plant_unzipped: Path, paper_toml: Path) -> None:
    """run_scenario with an extracted copy (what a battery worker passes) keeps the plant
    for the next controller and run (fmi2Reset); the results are those of fresh instances."""
    import dataclasses

    from papwc import scenario_run as runner
    from papwc.scenario import load_scenario

    scenario = load_scenario(paper_toml)
    maneuver = dataclasses.replace(scenario.maneuver, iterations=2, duration=0.5)
    scenario = dataclasses.replace(scenario, maneuver=maneuver)
    runner._IDLE_PLANTS.clear()
    fresh = runner.run_scenario(scenario, "fmu", friction_plant_fmu)
    assert runner._IDLE_PLANTS == {}  # without an extracted copy: closed after each use
    reused = [runner.run_scenario(scenario, "fmu", friction_plant_fmu,
                                  unzip_dir=friction_plant_unzipped) for _ in range(2)]
    try:
        (kept,) = runner._IDLE_PLANTS.values()
        assert kept.reusable
        for results in reused:
            assert [r.error for r in results] == [r.error for r in fresh]
            for a, b in zip(results, fresh, strict=True):
                assert [t.columns["x"] for t in a.traces] == [t.columns["x"] for t in b.traces]
        assert len(fresh) > 1 and fresh[0].traces
    finally:
        for slave in runner._IDLE_PLANTS.values():
            slave.close()
        runner._IDLE_PLANTS.clear()


@pytest.mark.slow
def test_papwc_build_backend_pythonfmu_writes_the_pythonfmu_plant(tmp_path: Path) -> None:
    from papwc.fmubuild.fmus import is_current
    from papwc.fmubuild.model_description import read_model_description as read_md

    out = tmp_path / "build"
    done = subprocess.run([sys.executable, "-m", "papwc.cli", "build", "--backend", "pythonfmu",
                           "--out", str(out)], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    plant = out / "FrictionPlant.fmu"
    assert read_md(plant).get("generationTool").startswith("PythonFMU")
    assert is_current(plant, "FrictionPlant", backend="pythonfmu")
    assert not is_current(plant, "FrictionPlant")  # not the native one
