"""Run the real ``xacro`` package in-process, without ROS, with legacy-xacro support.

xacro keeps its state in module globals, so each run holds a module lock and, inside it,
temporarily replaces: ``$(find)`` (-> :func:`find_package`, asked for by the file being read),
``xacro.parse`` (-> legacy tag upgrade of every file read), ``xacro.handle_macro_call`` (->
unprefixed macro calls), ``xacro.grab_macro`` (-> the macros defined) and xacro's stderr
printing (-> warnings). Everything is restored afterwards and xacro's exceptions become
:class:`ModelError` with file and line where they can be found.
"""

from __future__ import annotations

import contextlib
import os
import re
import threading
import warnings
import xml.dom.minidom
import xml.parsers.expat
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import xacro
import xacro.color
import xacro.substitution_args as substitution_args

from smartcar_gym.model.errors import ModelError, XacroWarning, read_utf8, xml_syntax_error
from smartcar_gym.model.legacy import LegacyReport, is_call_candidate, upgrade_tags
from smartcar_gym.model.packages import PackagePath, find_package

_LOCK = threading.RLock()


@dataclass(frozen=True)
class Expansion:
    """xacro's output: URDF ``text``, what each ``$(find pkg)`` resolved to, the files read."""

    text: str
    packages: dict[str, Path]
    files: tuple[str, ...]


class _Session:
    """State of one xacro run: files read, legacy upgrades, packages, macros, search path."""

    def __init__(self, package_path: PackagePath, legacy: bool) -> None:
        self.package_path = package_path
        self.legacy = legacy
        self.report = LegacyReport()
        self.files: list[str] = []
        self.packages: dict[str, Path] = {}  # first resolution of each package, for reports
        self.found: dict[tuple[str, str | None], str] = {}  # (package, asking file) -> folder
        self.macros: dict[str, str | None] = {}  # macro name -> file defining it
        self.calls = 0  # macro calls expanded
        self.unknown: dict[str, str | None] = {}  # unprefixed non-macro tag -> file using it

    # -- hooks ---------------------------------------------------------------------------
    def find(self, pkg: str) -> str:
        """``$(find pkg)``: the package folder, searched from the asking file (cached)."""
        asker = current_file()
        if (pkg, asker) not in self.found:
            line = locate_line(asker, f"$(find {pkg})") if asker else None
            found = find_package(pkg, self.package_path, requested_by=asker, line=line)
            self.found[pkg, asker] = str(found)
            self.packages.setdefault(pkg, found)
        return self.found[pkg, asker]

    def parse(self, original, inp, filename=None):
        """xacro.parse, with XML and encoding errors located and legacy tags upgraded."""
        try:
            doc = original(inp, filename)
        except xml.parsers.expat.ExpatError as exc:
            stack = [f for f in (xacro.filestack or []) if f]
            parent = f" (included from {stack[-2]})" if len(stack) > 1 else ""
            raise xml_syntax_error(exc, filename or current_file(), parent) from None
        except UnicodeDecodeError:
            if filename is None:
                raise
            read_utf8(os.path.join(xacro.root_dir, filename))  # raises the located ModelError
            raise
        if filename is not None:
            self.files.append(str(filename))
            if self.legacy:
                self.report.add_tags(str(filename), upgrade_tags(doc))
        return doc

    def handle_macro_call(self, original, node, macros, symbols):
        """xacro.handle_macro_call, also taking ``<name/>`` for a call of defined macro name."""
        tag = node.tagName
        if self.legacy and is_call_candidate(tag):
            try:
                xacro.resolve_macro(tag, macros, symbols)
            except (KeyError, TypeError, AttributeError):
                self.unknown.setdefault(tag, current_file())
            else:
                self.report.add_call(current_file() or "<string>", tag)
                node.tagName = node.nodeName = f"xacro:{tag}"
        called = original(node, macros, symbols)
        self.calls += bool(called)
        return called

    def grab_macro(self, original, element, macros) -> None:
        """xacro.grab_macro, recording the macro's name and the file defining it."""
        name = element.getAttribute("name").removeprefix("xacro:")
        self.macros.setdefault(name, current_file())
        original(element, macros)


def _no_links_error(doc: xml.dom.minidom.Document, session: _Session,
                   source: Path) -> ModelError | None:
    """Why an upgraded (legacy) document has no links, when macros explain it; else None."""
    root = doc.documentElement
    if not session.legacy or root.getElementsByTagName("link"):
        return None
    robot = f"robot '{root.getAttribute('name')}' has no links"
    defined = ", ".join(session.macros) or "none"
    unknown = [e.tagName for e in root.childNodes
               if e.nodeType == e.ELEMENT_NODE and is_call_candidate(e.tagName)]
    if unknown:
        tags = list(dict.fromkeys(unknown))
        listed = ", ".join(f"<{t}/>" for t in tags)
        where = session.unknown.get(tags[0]) or str(source)
        return ModelError(f"{robot}: no macro is defined for {listed}, so xacro kept "
                          f"{'it' if len(tags) == 1 else 'them'} as plain XML; defined macros: "
                          f"{defined}; expected a call of a defined macro (misspelled?)",
                          file=where, line=locate_line(where, f"<{tags[0]}"))
    if session.macros and not session.calls:
        own = [n for n, f in session.macros.items() if f == str(source)] or list(session.macros)
        macros = f"macros {defined} but never calls one" if len(session.macros) > 1 else (
            f"macro {defined} but never calls it")
        return ModelError(
            f"{robot}: the file defines {macros} (it is meant to be included); expected a call "
            f"such as <xacro:{own[0]}/>, or load the file that includes and calls it",
            file=source, line=locate_line(source, f'name="{own[0]}"'))
    return None


def current_file() -> str | None:
    """The file xacro is working on: the innermost macro's definition file, else the top file."""
    for macro in reversed(xacro.macrostack or []):
        if macro.history and macro.history[-1] and macro.history[-1][-1]:
            return str(macro.history[-1][-1])
    stack = [f for f in (xacro.filestack or []) if f]
    return str(stack[-1]) if stack else None


def locate_line(file: str | os.PathLike, needle: str) -> int | None:
    """First line (1-based) of ``file`` containing ``needle``, or None."""
    try:
        text = Path(file).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return None
    for number, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            return number
    return None


def _xacro_message(*args, **kwargs) -> None:
    text = " ".join(str(a) for a in args).strip()
    if text:
        where = current_file()
        warnings.warn(f"xacro: {text}" + (f" ({where})" if where else ""), XacroWarning, 3)


@contextlib.contextmanager
def _hooked(session: _Session) -> Iterator[None]:
    """Install the session's hooks into xacro's globals; restore all of them afterwards."""
    with _LOCK:
        saved = {
            "parse": xacro.parse,
            "handle_macro_call": xacro.handle_macro_call,
            "grab_macro": xacro.grab_macro,
            "print_location": xacro.print_location,
            "filestack": xacro.filestack,
            "macrostack": xacro.macrostack,
            "verbosity": xacro.verbosity,
            "all_includes": list(xacro.all_includes),
            "context": dict(xacro.substitution_args_context),
        }
        saved_message = xacro.color.message
        saved_find = substitution_args._eval_find
        saved_eval_find = substitution_args._eval_dict.get("find")
        parse, call, grab = saved["parse"], saved["handle_macro_call"], saved["grab_macro"]
        try:
            xacro.parse = lambda inp, filename=None: session.parse(parse, inp, filename)
            xacro.handle_macro_call = lambda n, m, s: session.handle_macro_call(call, n, m, s)
            xacro.grab_macro = lambda e, m: session.grab_macro(grab, e, m)
            xacro.print_location = lambda: None
            xacro.color.message = _xacro_message
            substitution_args._eval_find = session.find
            substitution_args._eval_dict["find"] = session.find
            yield
        finally:
            for name in ("parse", "handle_macro_call", "grab_macro", "print_location",
                         "filestack"):
                setattr(xacro, name, saved[name])
            xacro.macrostack = saved["macrostack"]
            xacro.verbosity = saved["verbosity"]
            xacro.all_includes[:] = saved["all_includes"]
            xacro.substitution_args_context.clear()
            xacro.substitution_args_context.update(saved["context"])
            xacro.color.message = saved_message
            substitution_args._eval_find = saved_find
            if saved_eval_find is not None:
                substitution_args._eval_dict["find"] = saved_eval_find


def _innermost(exc: BaseException) -> BaseException:
    """Unwrap XacroException chains down to the exception that caused them."""
    while isinstance(exc, xacro.XacroException) and exc.exc is not None:
        exc = exc.exc
    return exc


_NEEDLES = (
    (re.compile(r"when evaluating expression '(.*)'", re.S), "${{{}}}"),
    (re.compile(r"unknown macro name: (\S+)"), "<{}"),
    (re.compile(r"Undefined substitution argument (\S+)"), "$(arg {})"),
    (re.compile(r"Undefined block \"(.*?)\""), 'name="{}"'),
)


_ENV_UNSET = re.compile(r"environment variable '(.*?)' is not set")


def _to_model_error(exc: Exception, session: _Session) -> ModelError:
    """A ModelError for an exception raised inside xacro, located as well as we can."""
    inner = _innermost(exc)
    if isinstance(inner, ModelError):
        return inner
    where = current_file()
    env = _ENV_UNSET.search(str(inner))
    if isinstance(inner, OSError) and inner.filename:
        message = f"cannot read included file {inner.filename}: {inner.strerror}"
        needle = Path(inner.filename).name
    elif isinstance(inner, substitution_args.SubstitutionException) and env:
        name = env.group(1)
        message = (f"xacro: environment variable '{name}' is not set (asked for by $(env "
                   f"{name})); expected it set, or $(optenv {name} default) in the file")
        needle = f"$(env {name})"
    elif isinstance(inner, substitution_args.SubstitutionException) and not isinstance(
            inner, substitution_args.ArgException):  # xacro words ArgException itself
        message = f"xacro: {' '.join(str(inner).split())}"
        needle = None
    else:
        text = " ".join(str(exc).split())
        message = f"xacro: {text}" if isinstance(exc, xacro.XacroException) else (
            f"xacro: {type(exc).__name__}: {text}"
        )
        needle = None
        for pattern, template in _NEEDLES:
            match = pattern.search(str(exc))
            if match:
                needle = template.format(match.group(1).strip())
                break
    line = None
    if needle:
        for file in dict.fromkeys([f for f in (where, *reversed(session.files)) if f]):
            line = locate_line(file, needle)
            if line is not None:
                where = file
                break
    if xacro.macrostack:
        names = [m.body.getAttribute("name") for m in xacro.macrostack if m.body is not None]
        message += f" (while expanding macro {' -> '.join(names)})"
    return ModelError(message, file=where, line=line)


def _cycle(chain: list[str]) -> list[str] | None:
    """The first loop in ``chain``: ``[a, b, a]`` for ``[top, a, b, a, b, ...]``; else None."""
    first: dict[str, int] = {}
    for index, item in enumerate(chain):
        if item in first:
            return chain[first[item]:index + 1]
        first[item] = index
    return None


def _recursion_error(exc: Exception) -> ModelError | None:
    """For a RecursionError inside xacro: the include cycle or macro recursion behind it.

    xacro pops its include stack only after an include succeeded, so it still holds the chain.
    """
    if not isinstance(_innermost(exc), RecursionError):
        return None
    files = [os.path.realpath(os.path.join(xacro.root_dir, f)) for f in xacro.filestack or []
             if f]
    cycle = _cycle(files)
    if cycle:
        return ModelError(
            f"xacro include cycle: {' -> '.join(cycle)} (each file includes the next), so the "
            "expansion never ends; expected no file to include itself, directly or through "
            "others", file=cycle[-2], line=locate_line(cycle[-2], Path(cycle[-1]).name))
    macros = [m.body.getAttribute("name") for m in xacro.macrostack or [] if m.body is not None]
    cycle = _cycle(macros)
    if cycle:
        where = current_file()
        line = locate_line(where, f"<xacro:{cycle[-1]}") if where else None
        return ModelError(
            f"xacro macro recursion: {' -> '.join(cycle)} calls itself without end; expected "
            "the recursion to stop (a <xacro:if> around the inner call)", file=where, line=line)
    return None


def expand_xacro(
    path: str | os.PathLike,
    *,
    mappings: Mapping[str, object] | None = None,
    package_path: PackagePath = None,
    legacy: bool = True,
) -> Expansion:
    """Expand the xacro file ``path`` (xacro args from ``mappings``) into URDF text."""
    source = Path(path).resolve()
    if not source.is_file():
        raise FileNotFoundError(f"no such xacro file: {source}")
    args = {str(k): str(v) for k, v in (mappings or {}).items()}
    session = _Session(package_path, legacy)
    with _hooked(session):
        try:
            doc = xacro.process_file(str(source), mappings=args, verbosity=0)
        except ModelError:
            raise
        except Exception as exc:  # xacro raises XacroException, RuntimeError, NameError...
            recursion = _recursion_error(exc)
            if recursion is not None:
                raise recursion from None  # not a traceback 1000 frames deep
            raise _to_model_error(exc, session) from exc
        finally:
            session.report.warn()
    error = _no_links_error(doc, session, source)
    if error is not None:
        raise error
    return Expansion(doc.toprettyxml(indent="  "), dict(session.packages), tuple(session.files))
