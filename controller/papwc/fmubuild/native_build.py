"""Build a native (C) FMI 2.0 Co-Simulation FMU with zig, for every desktop platform.

:func:`build_native` makes ``<Model>.fmu`` from

- the FMI glue written once for every native FMU (``fmu_src/fmi2/``: ``fmi2_cs.c``,
  ``fmu_model.h``),
- the model's C files (``fmu_src/<Model>/*.c``, ``*.h``),
- headers generated from the model layer: the model's tables
  (:data:`papwc.fmubuild.native_tables.GENERATED_HEADERS`: ``plant_vars.h``,
  ``controller_vars.h``) and ``fmu_config.h`` (model identifier, GUID and the words of each
  parameter's range, :func:`config_header`),
- the FMI 2.0 headers shipped in fmpy (``fmpy/c-code``);

compiled with zig's C compiler (pip ``ziglang``: ``python -m ziglang cc``) for

========== ======================= ================================================
folder     target                  what it needs at run time
========== ======================= ================================================
linux64    x86_64-linux-gnu.2.17   glibc >= 2.17 (libc, libm); no libgcc_s, libstdc++
win64      x86_64-windows-gnu      KERNEL32 and the system C runtime
darwin64   x86_64-macos.10.13 +    libSystem of macOS 10.13 (x86_64) or 11 (arm64) or
           aarch64-macos.11.0      later; one universal (fat) Mach-O of both
========== ======================= ================================================

The archive holds ``sources/`` (every C file and header, with ``<SourceFiles>`` in the
model description, so a tool can build the FMU for another platform),
``documentation/`` (``index.html``: the equations, the variables with units and ranges
from the model layer, a plot of the reference result; the model's readme) and
``licenses/``. The model description is written from the model layer and completed as a
pythonfmu FMU's is (:func:`papwc.fmubuild.model_description.complete_model_description`);
the archive is written reproducibly and checked with ``fmpy.validation.validate_fmu``.
Every failure raises :class:`papwc.errors.BuildError` naming the FMU and the problem.
"""

from __future__ import annotations

import contextlib
import hashlib
import html
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from papwc import __version__
from papwc.errors import BuildError
from papwc.fmubuild.model_description import (
    MODEL_DESCRIPTION,
    complete_model_description,
    install_fmu,
    rewrite_fmu,
    xml_number,
)
from papwc.model.variables import Variable

__all__ = [
    "C_FLAGS",
    "ZIG_VERSION",
    "FMI2_HEADERS",
    "TARGETS",
    "NativeSource",
    "build_native",
    "config_header",
    "fat_macho",
    "fmi_headers_dir",
    "host_compiler",
    "prepared_tree",
    "zig_command",
]

#: Flags of every compile: C99, the same floating-point operations as written (no
#: contraction into fused multiply-adds, no fast math), only the fmi2 functions exported.
C_FLAGS: tuple[str, ...] = ("-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math",
                            "-fvisibility=hidden", "-Wall", "-Wextra", "-Wno-unused-parameter")

#: FMI platform folder -> (zig targets, file suffix, extra flags).
TARGETS: dict[str, tuple[tuple[str, ...], str, tuple[str, ...]]] = {
    "linux64": (("x86_64-linux-gnu.2.17",), ".so", ("-fPIC", "-static-libgcc", "-lm")),
    "win64": (("x86_64-windows-gnu",), ".dll", ()),
    # the oldest macOS each declares (zig's default would be the newest, 15.0)
    "darwin64": (("x86_64-macos.10.13", "aarch64-macos.11.0"), ".dylib", ("-fPIC",)),
}

#: The FMI 2.0 headers a native FMU is compiled against (from fmpy's ``c-code``).
FMI2_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")

#: The glue's folder under fmu_src/.
GLUE = "fmi2"
#: The glue's files.
GLUE_FILES = ("fmi2_cs.c", "fmu_model.h")


def fmi_headers_dir() -> Path:
    """The folder of the FMI headers shipped in fmpy."""
    import fmpy

    folder = Path(fmpy.__file__).resolve().parent / "c-code"
    missing = [h for h in FMI2_HEADERS if not (folder / h).is_file()]
    if missing:
        raise BuildError(f"fmpy's FMI headers {missing} are missing from {folder}; "
                         "reinstall fmpy (pip install --force-reinstall fmpy)")
    return folder


def zig_command() -> list[str]:
    """The command of zig's C compiler (pip ``ziglang``, :data:`ZIG_VERSION`).

    Raises
    ------
    BuildError
        If zig is not installed, or another version than :data:`ZIG_VERSION` is.
    """
    found = zig_version()
    if found != ZIG_VERSION:
        why = ("zig is not installed" if found is None
               else f"ziglang {found} is installed, which compiles other bytes")
        raise BuildError(
            "the FMU sources changed since papwc was installed, so its native FMUs must be "
            f"compiled again, with ziglang {ZIG_VERSION}, and {why}: pip install "
            f"'ziglang=={ZIG_VERSION}' (in a checkout: pip install -e '.[build]')")
    return [sys.executable, "-m", "ziglang", "cc"]


#: The zig (pip ``ziglang``) the native FMUs are compiled with, pinned in pyproject.toml's
#: build requirements and ``build`` extra: another version gives other bytes, so it is part
#: of a native FMU's digest and a compile with another one is refused.
ZIG_VERSION = "0.17.1"


def zig_cache_dir() -> Path:
    """zig's global cache: ``ZIG_GLOBAL_CACHE_DIR``, else a private one per user in the temp
    folder (compiled objects and the C runtimes of every target)."""
    return Path(os.environ.get("ZIG_GLOBAL_CACHE_DIR")
                or Path(tempfile.gettempdir()) / "papwc-zig-cache")


def host_compiler(variable: str = "PAPWC_CC") -> list[str] | None:
    """A C compiler for this machine (not a cross-compiler): the environment variable
    ``variable`` (a command, split at spaces), else the system ``cc``, ``gcc`` or ``clang``,
    else zig's (pip ``ziglang``); None if there is none."""
    import importlib.util

    chosen = os.environ.get(variable, "").split()
    if chosen:
        return chosen
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return [path]
    if importlib.util.find_spec("ziglang") is not None:
        return [sys.executable, "-m", "ziglang", "cc"]
    return None


def zig_version() -> str | None:
    """The version of the installed zig (pip ``ziglang``), or None if it is not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("ziglang")
    except PackageNotFoundError:
        return None


@dataclass(frozen=True)
class NativeSource:
    """What one native FMU is built from.

    Attributes
    ----------
    name : str
        Model identifier; ``fmu_src/<name>/`` holds the model's C files.
    folder : Path
        ``fmu_src/<name>/``.
    glue : Path
        ``fmu_src/fmi2/``.
    variables : tuple of Variable
        Every variable, in the order of their value references.
    description : str
        One line: what the model is.
    documentation : tuple of Path
        Files copied into ``documentation/`` (the readme).
    reference : Path or None
        The reference result (``<name>_ref.csv``) plotted in ``index.html``.
    sections : tuple of str
        Headings of the readme's sections copied into ``index.html`` (the equations).
    default_experiment : (float, float, float)
        Start time, stop time and step size, s.
    variable_step : bool
        ``canHandleVariableCommunicationStepSize`` (a sampled controller: False).
    """

    name: str
    folder: Path
    glue: Path
    variables: tuple[Variable, ...]
    description: str
    documentation: tuple[Path, ...] = ()
    reference: Path | None = None
    sections: tuple[str, ...] = ()
    default_experiment: tuple[float, float, float] = (0.0, 1.0, 0.01)
    variable_step: bool = True

    def c_files(self) -> list[Path]:
        """The C sources and headers written by hand (glue and model), sorted."""
        files = [self.glue / f for f in GLUE_FILES]
        files += sorted(p for p in self.folder.iterdir() if p.suffix in (".c", ".h"))
        return files

    def check(self) -> None:
        """Raise BuildError if a source is missing."""
        for path in (*[self.glue / f for f in GLUE_FILES], *self.documentation):
            if not Path(path).is_file():
                raise BuildError(f"cannot build {self.name}.fmu: source file {path} does "
                                 "not exist")
        if not any(p.suffix == ".c" for p in self.folder.iterdir()):
            raise BuildError(f"cannot build {self.name}.fmu: no C source in {self.folder}")

    def generated(self) -> dict[str, str]:
        """The generated headers (file name -> text), without the GUID."""
        from papwc.fmubuild.native_tables import GENERATED_HEADERS

        return {name: write() for name, write in GENERATED_HEADERS.get(self.name, {}).items()}

    def digest(self) -> str:
        """SHA-256 (hex) of everything the FMU is built from (sources, tables, flags, zig)."""
        h = hashlib.sha256()

        def add(label: str, data: bytes) -> None:
            h.update(label.encode() + b"\0" + len(data).to_bytes(8, "little") + data)

        for path in self.c_files():
            add("c:" + path.name, path.read_bytes())
        for name, text in sorted(self.generated().items()):
            add("gen:" + name, text.encode())
        for path in sorted(Path(p) for p in self.documentation):
            add("doc:" + path.name, path.read_bytes())
        if self.reference is not None:
            add("ref", Path(self.reference).read_bytes())
        add("extra", repr((list(self.variables), self.description, self.sections,
                           self.default_experiment, self.variable_step, C_FLAGS,
                           sorted(TARGETS.items()),
                           ZIG_VERSION, _words(self.variables))).encode())
        add("builder", Path(__file__).read_bytes())
        return h.hexdigest()


def _words(variables: Sequence[Variable]) -> list[tuple[int, str, str]]:
    """(value reference, unit suffix, what is allowed) of each Real or Integer parameter."""
    out = []
    for vr, var in enumerate(variables):
        if var.causality == "parameter" and var.type in ("Real", "Integer"):
            out.append((vr, var.unit_suffix, var._range_message()))
    return out


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def config_header(name: str, guid_text: str, variables: Sequence[Variable]) -> str:
    """The text of ``fmu_config.h``: model identifier, GUID, the words of each range."""
    lines = [
        f"/* fmu_config.h: {name}'s identity and the words of its parameters' ranges,",
        " * generated by papwc.fmubuild.native_build from the model layer. Do not edit. */",
        "#ifndef PAPWC_FMU_CONFIG_H",
        "#define PAPWC_FMU_CONFIG_H",
        f"#define MODEL_IDENTIFIER_STRING {_c_string(name)}",
        f"#define MODEL_GUID {_c_string(guid_text)}",
        "/* X(value reference, unit suffix, what is allowed) */",
        "#define FMU_PARAMETER_WORDS(X) \\",
    ]
    entries = [f"    X({vr}, {_c_string(unit)}, {_c_string(words)})"
               for vr, unit, words in _words(variables)]
    lines.append(" \\\n".join(entries))
    lines += ["#endif", ""]
    return "\n".join(lines)


# --- compiling --------------------------------------------------------------------------------


def _compile(tree: Path, target: str, extra: Sequence[str], out: Path, name: str) -> None:
    """Compile ``tree/sources/*.c`` for ``target`` into ``out`` (a path inside ``tree``).

    zig runs in ``tree`` with relative paths only, so no path of the build folder ends up
    in the binary: the same sources give the same bytes.
    """
    c_files = sorted(p.relative_to(tree).as_posix() for p in (tree / "sources").glob("*.c"))
    relative = out.relative_to(tree).as_posix()
    command = [*zig_command(), "-target", target, *C_FLAGS, "-shared", "-s", *extra,
               "-I", "sources", "-o", relative, *c_files]
    env = dict(os.environ)
    env["ZIG_GLOBAL_CACHE_DIR"] = str(zig_cache_dir())
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=600, env=env,
                              check=False, cwd=str(tree))
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise BuildError(f"cannot build {name}.fmu for {target}: zig did not run: {exc}") from exc
    if done.returncode != 0:
        raise BuildError(f"cannot build {name}.fmu for {target}: zig cc exited with "
                         f"{done.returncode}: {(done.stderr or done.stdout).strip()[-2000:]}")
    if not out.is_file():
        raise BuildError(f"cannot build {name}.fmu for {target}: zig wrote no {out.name}")


def fat_macho(thin: Sequence[bytes]) -> bytes:
    """One universal (fat) Mach-O holding the thin Mach-O files ``thin``.

    The fat header (big-endian): magic 0xCAFEBABE, the number of architectures, then per
    architecture its CPU type and subtype (read from the thin file's header), offset, size
    and alignment (2^14: every file starts on a 16 KiB page, as arm64 needs).
    """
    align = 14
    header = struct.pack(">II", 0xCAFEBABE, len(thin))
    offset = (len(header) + 20 * len(thin) + (1 << align) - 1) >> align << align
    entries, body = [], b""
    for data in thin:
        magic, cputype, cpusubtype = struct.unpack_from("<III", data, 0)
        if magic != 0xFEEDFACF:
            raise BuildError(f"not a 64-bit Mach-O file (magic {magic:#x})")
        start = offset + len(body)
        entries.append(struct.pack(">IIIII", cputype, cpusubtype, start, len(data), align))
        body += data
        pad = (-len(body)) % (1 << align)
        body += b"\0" * pad
    head = header + b"".join(entries)
    return head + b"\0" * (offset - len(head)) + body


def compile_binaries(tree: Path, name: str,
                     more: dict[str, tuple[str, ...]] | None = None) -> list[Path]:
    """Compile ``tree/sources/*.c`` for every platform of :data:`TARGETS` into
    ``tree/binaries/<platform>/`` (``more``: further flags by platform folder)."""
    from papwc import progress

    binaries = tree / "binaries"
    written = []
    cache = zig_cache_dir()
    if not any((cache / "o").glob("*")):
        progress.note_once("zig runtimes", f"the first build compiles zig's C runtimes for "
                           f"{', '.join(TARGETS)} into {cache}: a few minutes, once; later "
                           "builds take seconds")
    for folder, (targets, suffix, extra) in TARGETS.items():
        extra = (*extra, *(more or {}).get(folder, ()))
        (binaries / folder).mkdir(parents=True, exist_ok=True)
        out = binaries / folder / f"{name}{suffix}"
        if suffix == ".dylib":  # the install name is the file's, not the build folder's
            extra = (*extra, f"-Wl,-install_name,@rpath/{name}{suffix}")
        if len(targets) == 1:
            progress.doing(f"compiling {name}.fmu's C sources for {folder} ({targets[0]}) "
                           "with zig")
            _compile(tree, targets[0], extra, out, name)
        else:
            thin = []
            for target in targets:
                progress.doing(f"compiling {name}.fmu's C sources for {folder} ({target}) "
                               "with zig")
                part = binaries / folder / f"{name}.{target}{suffix}"
                _compile(tree, target, extra, part, name)
                thin.append(part.read_bytes())
                part.unlink()
            out.write_bytes(fat_macho(thin))
        for junk in (binaries / folder).iterdir():  # import libraries, debug files
            if junk != out:
                junk.unlink()
        written.append(out)
    return written


# --- model description, documentation, licenses --------------------------------------------

_CAUSALITY_ORDER = ("parameter", "input", "output")


def model_description_skeleton(source: NativeSource, guid_text: str,
                               source_files: Sequence[str]) -> ET.Element:
    """The model description's elements a pythonfmu build would write (completed later)."""
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": source.name, "guid": guid_text,
        "description": source.description, "author": "papwc", "version": __version__,
        "license": "BSD-2-Clause", "generationTool": "papwc (native FMU, zig)",
        "variableNamingConvention": "structured", "numberOfEventIndicators": "0",
    })
    cs = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": source.name,
        "needsExecutionTool": "false",
        "canHandleVariableCommunicationStepSize": "true" if source.variable_step else "false",
        "canInterpolateInputs": "false",
        "maxOutputDerivativeOrder": "0",
        "canRunAsynchronuously": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "true",
        "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true",
        "providesDirectionalDerivative": "false",
    })
    files = ET.SubElement(cs, "SourceFiles")
    for file in source_files:
        ET.SubElement(files, "File", name=file)
    categories = ET.SubElement(root, "LogCategories")
    for name, text in (("logStatusError", "Refused calls (fmi2Error), one message each"),
                       ("logStatusDiscard", "Refused steps (fmi2Discard), one message each"),
                       ("logAll", "Every message")):
        ET.SubElement(categories, "Category", name=name, description=text)
    variables = ET.SubElement(root, "ModelVariables")
    for vr, var in enumerate(source.variables):
        attrs = {"name": var.name, "valueReference": str(vr), "causality": var.causality,
                 "variability": var.fmi_variability}
        if var.causality == "parameter":
            attrs["initial"] = "exact"
        sv = ET.SubElement(variables, "ScalarVariable", attrs)
        ET.SubElement(sv, var.type)
    return root


def _plot(reference: Path, target: Path) -> None:
    """A PNG of the reference result (x and v over time)."""
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(reference, newline="") as f:
        rows = list(csv.DictReader(f))
    t = [float(r["time"]) for r in rows]
    fig, (ax_x, ax_v) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    ax_x.plot(t, [float(r["x"]) * 1e3 for r in rows], drawstyle="default")
    ax_x.set_ylabel("x (mm)")
    ax_v.plot(t, [float(r["v"]) for r in rows], color="tab:red")
    ax_v.set_ylabel("v (m/s)")
    ax_v.set_xlabel("t (s)")
    ax_x.set_title(f"{reference.stem.removesuffix('_ref')}: reference result (default "
                   "parameters, force of _in.csv)")
    for ax in (ax_x, ax_v):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(target, dpi=90, metadata={"Software": None})
    plt.close(fig)


def _allowed(var: Variable) -> str:
    return var.allowed_text() if var.causality == "parameter" else ""


def _markdown_to_html(text: str) -> str:
    """The paragraphs, lists and code blocks of a Markdown section as HTML (nothing more)."""
    out, paragraph, code = [], [], None
    for line in text.splitlines():
        if line.startswith("```"):
            if code is None:
                if paragraph:
                    out.append(f"<p>{html.escape(' '.join(paragraph))}</p>")
                    paragraph = []
                code = []
            else:
                out.append("<pre>" + html.escape("\n".join(code)) + "</pre>")
                code = None
        elif code is not None:
            code.append(line)
        elif not line.strip():
            if paragraph:
                out.append(f"<p>{html.escape(' '.join(paragraph))}</p>")
                paragraph = []
        else:
            paragraph.append(line.strip())
    if paragraph:
        out.append(f"<p>{html.escape(' '.join(paragraph))}</p>")
    return "\n".join(out)


def readme_sections(source: NativeSource) -> str:
    """The readme's sections named in ``source.sections`` as HTML."""
    readme = next((Path(p) for p in source.documentation if Path(p).suffix == ".md"), None)
    if readme is None or not source.sections:
        return ""
    text = readme.read_text(encoding="utf-8")
    parts = []
    for heading in source.sections:
        marker = f"\n## {heading}\n"
        if marker not in text:
            raise BuildError(f"{readme}: has no section '## {heading}' for index.html")
        body = text.split(marker, 1)[1].split("\n## ", 1)[0]
        parts.append(f"<h2>{html.escape(heading)}</h2>\n{_markdown_to_html(body)}")
    return "\n".join(parts)


def index_html(source: NativeSource, plot: str | None) -> str:
    """``documentation/index.html``: equations, variables (units, ranges), the plot."""
    e = html.escape
    rows = []
    for vr, var in enumerate(source.variables):
        start = ("calculated" if var.causality == "output" and var.initial == "calculated"
                 else xml_number(var.fmi_start))
        unit = var.unit if var.unit not in ("", "1") else "&ndash;"
        rows.append(f"<tr><td><code>{e(var.name)}</code></td><td>{vr}</td>"
                    f"<td>{e(var.causality)}</td><td>{e(var.type)}</td><td>{unit}</td>"
                    f"<td>{e(start)}</td><td>{e(_allowed(var)) or '&ndash;'}</td>"
                    f"<td>{e(var.description)}</td></tr>")
    figure = (f'<h2>Reference result</h2>\n<p><img src="{plot}" alt="reference result"></p>\n'
              f"<p>{e(source.name)}_ref.csv (in this folder) with the force of "
              f"{e(source.name)}_in.csv and the default parameters.</p>") if plot else ""
    return f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>{e(source.name)}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;
font-size:90%}}</style></head>
<body>
<h1>{e(source.name)}</h1>
<p>{e(source.description)}</p>
<p>FMI 2.0 Co-Simulation, compiled from C (the sources are in <code>sources/</code>) for
win64, linux64 (glibc 2.17 or newer) and darwin64 (x86_64: macOS 10.13 or newer; arm64:
macOS 11 or newer). No Python is needed
to run it. Every refused call returns fmi2Error (fmi2Discard for a step with a non-finite
input or a step size that is not &gt; 0) and logs why when logging is on.</p>
{readme_sections(source)}
<h2>Variables</h2>
<table><tr><th>name</th><th>value reference</th><th>causality</th><th>type</th><th>unit</th>
<th>start</th><th>allowed</th><th>description</th></tr>
{chr(10).join(rows)}
</table>
{figure}
<p>More: <a href="readme.md">readme.md</a>. License: <a href="../licenses/LICENSE.txt">
BSD-2-Clause</a>.</p>
</body></html>
"""


PROJECT_LICENSE = """BSD 2-Clause License

Copyright (c) 2026, the papwc authors
All rights reserved.

Redistribution and use in source and binary forms, with or without modification, are
permitted provided that the following conditions are met:

1. Redistributions of source code must retain the above copyright notice, this list of
   conditions and the following disclaimer.

2. Redistributions in binary form must reproduce the above copyright notice, this list of
   conditions and the following disclaimer in the documentation and/or other materials
   provided with the distribution.

THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS "AS IS" AND ANY EXPRESS
OR IMPLIED WARRANTIES, INCLUDING, BUT NOT LIMITED TO, THE IMPLIED WARRANTIES OF
MERCHANTABILITY AND FITNESS FOR A PARTICULAR PURPOSE ARE DISCLAIMED. IN NO EVENT SHALL THE
COPYRIGHT HOLDER OR CONTRIBUTORS BE LIABLE FOR ANY DIRECT, INDIRECT, INCIDENTAL, SPECIAL,
EXEMPLARY, OR CONSEQUENTIAL DAMAGES (INCLUDING, BUT NOT LIMITED TO, PROCUREMENT OF
SUBSTITUTE GOODS OR SERVICES; LOSS OF USE, DATA, OR PROFITS; OR BUSINESS INTERRUPTION)
HOWEVER CAUSED AND ON ANY THEORY OF LIABILITY, WHETHER IN CONTRACT, STRICT LIABILITY, OR
TORT (INCLUDING NEGLIGENCE OR OTHERWISE) ARISING IN ANY WAY OUT OF THE USE OF THIS
SOFTWARE, EVEN IF ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.
"""


def project_license() -> str:
    """The project's license text (LICENSE of a checkout, else the text above)."""
    from papwc.resources import checkout_root

    root = checkout_root()
    if root is not None and (root / "LICENSE").is_file():
        return (root / "LICENSE").read_text(encoding="utf-8")
    return PROJECT_LICENSE


def _fmi_header_notice(headers: Path) -> str:
    """The copyright and license lines of the FMI headers (kept with the headers)."""
    text = (headers / "fmi2Functions.h").read_text(encoding="utf-8", errors="replace")
    start = text.find("Copyright")
    end = text.find("ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.")
    if start < 0 or end < 0:
        raise BuildError(f"{headers / 'fmi2Functions.h'}: its license notice was not found")
    lines = text[start:end + len("ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.")].splitlines()
    return "\n".join(line.strip() for line in lines) + "\n"


# --- the archive ------------------------------------------------------------------------------


@contextlib.contextmanager
def prepared_tree(source: NativeSource) -> Iterator[Path]:
    """A temporary folder ``fmu/`` whose ``sources/`` holds everything the binaries of
    ``source`` are compiled from: the glue and model C files, the FMI headers, the generated
    headers and ``fmu_config.h`` (with the GUID made of the source's digest); removed after.
    """
    from papwc.fmubuild.pythonfmu_build import guid

    headers = fmi_headers_dir()
    work = Path(tempfile.mkdtemp(prefix="papwc_native_"))
    try:
        tree = work / "fmu"
        sources = tree / "sources"
        sources.mkdir(parents=True)
        for path in source.c_files():
            shutil.copyfile(path, sources / path.name)
        for header in FMI2_HEADERS:
            shutil.copyfile(headers / header, sources / header)
        for file_name, text in source.generated().items():
            (sources / file_name).write_text(text, encoding="utf-8")
        (sources / "fmu_config.h").write_text(
            config_header(source.name, guid(source.digest()), source.variables),
            encoding="utf-8")
        yield tree
    finally:
        shutil.rmtree(work, ignore_errors=True)



def build_native(source: NativeSource, out_dir: Path) -> Path:
    """Compile ``source`` with zig for every platform, write its model description from the
    variable table, and check the archive with fmpy's validation.

    Parameters
    ----------
    source : NativeSource
        The model's C files, generated tables, documentation and reference result.
    out_dir : Path
        Where ``<name>.fmu`` goes (created if needed); an FMU already there is replaced
        only once the new one is complete.

    Returns
    -------
    Path
        Path of ``<name>.fmu`` in ``out_dir``.

    Raises
    ------
    BuildError
        A source is missing, zig fails, or fmpy reports a validation problem.
    OutputError
        The FMU cannot be written into ``out_dir``.
    """
    from fmpy.validation import validate_fmu

    from papwc.fmubuild.prebuilt import binaries
    from papwc.fmubuild.pythonfmu_build import guid

    source.check()
    name = source.name
    headers = fmi_headers_dir()
    with prepared_tree(source) as tree:
        work = tree.parent
        guid_text = guid(source.digest())
        binaries(tree, name)  # those compiled when papwc was installed, else zig's
        docs = tree / "documentation"
        docs.mkdir()
        for doc in source.documentation:
            shutil.copyfile(doc, docs / Path(doc).name)
        plot = None
        if source.reference is not None:
            plot = "reference.png"
            _plot(Path(source.reference), docs / plot)
            shutil.copyfile(source.reference, docs / Path(source.reference).name)
        (docs / "index.html").write_text(index_html(source, plot), encoding="utf-8")
        licenses = tree / "licenses"
        licenses.mkdir()
        (licenses / "LICENSE.txt").write_text(project_license(), encoding="utf-8")
        (licenses / "FMI-headers-LICENSE.txt").write_text(
            "sources/fmi2Functions.h, fmi2FunctionTypes.h, fmi2TypesPlatform.h: the FMI 2.0 "
            "headers of the Modelica Association Project FMI (as shipped in fmpy)\n\n"
            + _fmi_header_notice(headers), encoding="utf-8")
        c_sources = sorted(p.name for p in (tree / "sources").glob("*.c"))
        root = model_description_skeleton(source, guid_text, c_sources)
        complete_model_description(root, source.variables, guid=guid_text,
                                   default_experiment=source.default_experiment,
                                   where=f"{name}.fmu")
        ET.indent(root, space="  ")
        (tree / MODEL_DESCRIPTION).write_bytes(
            ET.tostring(root, encoding="UTF-8", xml_declaration=True))
        built = work / f"{name}.fmu"
        with zipfile.ZipFile(built, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(p for p in tree.rglob("*") if p.is_file()):
                archive.write(path, path.relative_to(tree).as_posix())
        rewrite_fmu(built)  # sorted members, fixed times and modes: the same bytes each build
        from papwc import progress

        progress.doing(f"checking {built.name} with fmpy's validation")
        problems = validate_fmu(str(built))
        if problems:
            raise BuildError(f"{built.name} is not valid: " + "; ".join(problems))
        return install_fmu(built, out_dir)
