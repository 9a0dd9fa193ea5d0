"""The project's FMUs: what each is built from (:data:`FMUS`), and building them.

A pythonfmu FMU is a folder of ``fmu_src/`` (the model script, its readme, a reference
result) plus a bundle of the project's own packages, copied under a package
name that no other FMU uses (pythonfmu FMUs in one process share one Python
interpreter, and modules of the same name would shadow each other):

FMU               bundle package             bundled subpackages of papwc
================= ========================== ==========================================
FrictionPlant     ``papwc_friction_plant``   ``model`` (physics, variables), ``fmi``
PulseController   ``papwc_pulse_controller`` ``model``, ``controllers``, ``fmi``
PapwcTrivial      (none)                     (none: the floor ``papwc bench`` measures)
================= ========================== ==========================================
=======
===================== ========================== =========================================
FMU                   bundle package             bundled subpackages of papwc
===================== ========================== =========================================
FrictionPlant         ``papwc_friction_plant``   ``model`` (physics, variables), ``fmi``
PulseControllerPython ``papwc_pulse_controller`` ``model``, ``controllers``, ``fmi``
PapwcTrivial          (none)                     (none: the floor ``papwc bench`` measures)
===================== ========================== =========================================

A native FMU is C (``fmu_src/<Model>/*.c`` with the FMI glue of ``fmu_src/fmi2/``), built
by :mod:`.native_build` for win64, linux64 and darwin64; it needs no Python in the host:

- FrictionPlant: native by default (:data:`DEFAULT_BACKEND`); ``backend="pythonfmu"``
  builds the pythonfmu one under the same name;
- PulseController: always native, the controller kinds the C controller implements
  (:data:`papwc.fmubuild.native_tables.NATIVE_KINDS`: pwc, papwc, pid);
  PulseControllerPython, always pythonfmu (``fmu_src/PulseController/PulseControllerPython.py``),
  has every kind (exact, dual_loop and hybrid only there) and the same variables. ClosedLoop.ssp
  takes PulseController.fmu for the kinds it has, else PulseControllerPython.fmu
  (:func:`controller_fmu_name`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import papwc
from papwc.errors import BuildError
from papwc.fmubuild.model_description import read_model_description
from papwc.fmubuild.pythonfmu_build import STATE_OPTIONS, FmuSource, build_pythonfmu, guid
from papwc.model.controller_settings import PULSE_CONTROLLER_VARIABLES
from papwc.model.plant import PLANT_VARIABLES
from papwc.model.variables import Variable
from papwc.resources import checkout_root, fmu_src_dir

__all__ = [
    "BACKENDS",
    "DEFAULT_BACKEND",
    "FMUS",
    "FmuRecipe",
    "build_all",
    "build_fmu",
    "current_fmu",
    "fmu_digest",
    "guid",
    "is_current",
    "controller_fmu_name",
    "recipe",
]

#: How FrictionPlant can be built: in C ("native", the default) or with pythonfmu.
BACKENDS = ("native", "pythonfmu")
#: The backend of ``papwc build``, ``run``, ``reproduce``, ``battery`` and ClosedLoop.ssp.
DEFAULT_BACKEND = "native"

#: The folder of the papwc package (its subpackages are bundled).
PACKAGE_DIR = Path(papwc.__file__).resolve().parent


@dataclass(frozen=True)
class FmuRecipe:
    """What one FMU is built from.

    Attributes
    ----------
    name : str
        Model identifier; ``fmu_src/<name>/<name>.py`` is the script.
    variables : tuple of Variable
        Every variable the model declares.
    package : str
        Bundle package name ("" for none).
    subpackages : tuple of str
        Subpackages of papwc copied into the bundle.
    options : dict
        CoSimulation capability flags.
    native : bool
        Whether the model is written in C (``fmu_src/<source>/*.c``).
    python : bool
        Whether it has a pythonfmu script (a native model without one is always native).
    folder_name : str
        Its folder in ``fmu_src/`` where that is not ``name``.
    sections : tuple of str
        The readme's sections copied into a native FMU's ``index.html``.
    loader : bool
        A pythonfmu FMU whose binary refuses in one line where the host has no Python
        (:func:`papwc.fmubuild.pythonfmu_build.add_loader`).
    """

    name: str
    variables: tuple[Variable, ...]
    package: str = ""
    subpackages: tuple[str, ...] = ()
    options: dict[str, bool] = field(default_factory=lambda: dict(STATE_OPTIONS))
    native: bool = False
    python: bool = True
    folder_name: str = ""
    sections: tuple[str, ...] = ("Equations",)
    loader: bool = False

    @property
    def folder(self) -> Path:
        """The model's folder in fmu_src/."""
        return fmu_src_dir() / (self.folder_name or self.name)

    @property
    def script(self) -> Path:
        """The model script."""
        return self.folder / f"{self.name}.py"

    @property
    def bundle(self) -> dict[str, Path]:
        """Subpackage name -> source folder."""
        return {name: PACKAGE_DIR / name for name in self.subpackages}

    @property
    def documentation(self) -> tuple[Path, ...]:
        """The readme, when there is one."""
        readme = self.folder / "readme.md"
        return (readme,) if readme.is_file() else ()

    def source(self) -> FmuSource:
        """What the FMU is built from, with the paths of this installation."""
        return FmuSource(self.script, self.variables, self.package, self.bundle,
                         self.documentation, options=self.options, loader=self.loader)

    def native_source(self):
        """What the native FMU is built from (:class:`.native_build.NativeSource`)."""
        from papwc.fmubuild.native_build import NativeSource

        reference = self.folder / f"{self.name}_ref.csv"
        return NativeSource(
            self.name, self.folder, fmu_src_dir() / "fmi2", self.variables,
            _DESCRIPTIONS.get(self.name, self.name), self.documentation,
            reference if reference.is_file() else None, sections=self.sections,
            variable_step=self.options.get("canHandleVariableCommunicationStepSize", True),
        )

    def uses_native(self, backend: str) -> bool:
        """Whether ``backend`` builds this FMU in C (a model without a pythonfmu script is
        built in C whatever the backend)."""
        if backend not in BACKENDS:
            raise BuildError(f"backend {backend!r}: must be one of " + ", ".join(BACKENDS))
        return self.native and (backend == "native" or not self.python)


#: One line on each native model (its model description's ``description``).
_DESCRIPTIONS = {
    "FrictionPlant": (
        "Mass with Coulomb, stiction and viscous friction (m*dv/dt = u - f_c*sgn(v) - c*v, "
        "stuck while v = 0 and |u| <= f_s), advanced exactly with the force held constant "
        "over each communication step; optional deviations of a real machine (Stribeck "
        "curve, LuGre pre-sliding, friction ripple, random stiction, actuator lag, flexible "
        "drive, encoder noise), integrated with error control where no closed form exists"
    ),
    "PulseController": (
        "Adaptive pulse controller for positioning a mass with stick-slip friction, in C: PWC "
        "(kind pwc, Eqs. (5)-(9)), PAPWC (papwc, Eqs. (10)-(18)) or the PID baseline (pid); "
        "at each communication step of size T it reads the measured position and the "
        "reference and sets the force to hold over the next sample (the kinds exact, "
        "dual_loop and hybrid: PulseControllerPython.fmu)"
    ),
}


#: The FMUs ``papwc build`` writes, in order.
FMUS: tuple[FmuRecipe, ...] = (
    FmuRecipe("FrictionPlant", PLANT_VARIABLES, "papwc_friction_plant", ("model", "fmi"),
              native=True),
    FmuRecipe("PulseController", PULSE_CONTROLLER_VARIABLES,
              options={**STATE_OPTIONS, "canHandleVariableCommunicationStepSize": False},
              native=True, python=False, sections=("Sampling", "The two builds")),
    FmuRecipe(
        "PulseControllerPython",
        PULSE_CONTROLLER_VARIABLES,
        "papwc_pulse_controller",
        ("model", "controllers", "fmi"),
        {**STATE_OPTIONS, "canHandleVariableCommunicationStepSize": False},
        folder_name="PulseController",
        loader=True,
    ),
    FmuRecipe(
        "PapwcTrivial",
        (
            Variable("u", "Input value", "1", 0.0, causality="input"),
            Variable("y", "Output value: the input at the last step", "1", 0.0,
                     causality="output", initial="exact"),
        ),
    ),
)


def recipe(name: str) -> FmuRecipe:
    """The recipe of FMU ``name`` (e.g. ``"FrictionPlant"``)."""
    for r in FMUS:
        if r.name == name:
            return r
    raise BuildError(f"no FMU named {name!r}; FMUs: " + ", ".join(r.name for r in FMUS))


def fmu_digest(name: str, backend: str = DEFAULT_BACKEND) -> str:
    """Digest of the sources FMU ``name`` would be built from now (its GUID is made of it)."""
    r = recipe(name)
    if r.uses_native(backend):
        return r.native_source().digest()
    return r.source().digest()


def build_fmu(name: str, out_dir: Path, backend: str = DEFAULT_BACKEND) -> Path:
    """Build FMU ``name`` into ``out_dir`` with ``backend``; return the path written."""
    from papwc import progress

    r = recipe(name)
    if r.uses_native(backend):
        from papwc.fmubuild.native_build import build_native

        progress.doing(f"building {name}.fmu (C: the binaries compiled when papwc was installed, "
                       "or by zig if its sources changed since)")
        return build_native(r.native_source(), out_dir)
    progress.doing(f"building {name}.fmu with pythonfmu")
    return build_pythonfmu(r.source(), out_dir)


def is_current(path: Path, name: str, backend: str = DEFAULT_BACKEND) -> bool:
    """Whether ``path`` is FMU ``name`` built with ``backend`` from the sources as they are."""
    try:
        found = read_model_description(path).get("guid")
    except BuildError:
        return False
    return found == guid(fmu_digest(name, backend))


def current_fmu(name: str, out_dir: Path, backend: str = DEFAULT_BACKEND) -> Path:
    """FMU ``name`` built from the current sources, building it only if needed.

    The checkout's ``build/<name>.fmu`` (what ``papwc build`` wrote) if it is
    current, else ``out_dir/<name>.fmu``, built there if missing or stale.
    """
    root = checkout_root()
    if root is not None and is_current(root / "build" / f"{name}.fmu", name, backend):
        return root / "build" / f"{name}.fmu"
    path = Path(out_dir) / f"{name}.fmu"
    if not is_current(path, name, backend):
        build_fmu(name, out_dir, backend)
    return path


def build_all(out_dir: Path, backend: str = DEFAULT_BACKEND) -> list[Path]:
    """Build every FMU of :data:`FMUS` into ``out_dir``; return the paths written.

    FrictionPlant is built with ``backend``; PulseController is native,
    PulseControllerPython and PapwcTrivial are pythonfmu FMUs.
    """
    return [build_fmu(r.name, out_dir, backend) for r in FMUS]


def controller_fmu_name(kind: str) -> str:
    """The controller FMU that runs kind ``kind``: PulseController (native) for the kinds
    of :data:`papwc.fmubuild.native_tables.NATIVE_KINDS`, else PulseControllerPython."""
    from papwc.fmubuild.native_tables import NATIVE_KINDS

    return "PulseController" if kind in NATIVE_KINDS else "PulseControllerPython"
