"""The docstrings of the public API: their examples run (doctest), and every public function,
class and method carries a numpydoc docstring with the sections it needs, so that a public
function added without documentation fails here."""

import doctest
import importlib
import inspect
import re
from dataclasses import fields, is_dataclass

import pytest

import eosim

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE

# Every module of the package (the public names live in several of them).
MODULES = ["eosim", "eosim._checks", "eosim._dataset", "eosim._errors", "eosim._keys",
           "eosim._progress", "eosim._sources", "eosim.bundles", "eosim.experiment",
           "eosim.pics"]


def _public():
    """``(name, object)`` of every public function and class: ``eosim.__all__`` (but
    ``__version__``) and the ``ds.eosim`` accessor."""
    out = [(n, getattr(eosim, n)) for n in eosim.__all__ if not n.startswith("__")]
    from eosim._dataset import EosimAccessor

    if EosimAccessor not in [o for _, o in out]:
        out.append(("EosimAccessor", EosimAccessor))
    return out


def _doctests():
    """Every doctest of the package's modules and public objects, each once (an object is
    found both in its module and through ``eosim``)."""
    finder = doctest.DocTestFinder(exclude_empty=True)
    seen, tests = set(), []
    sources = [(m, importlib.import_module(m)) for m in MODULES]
    sources += [(f"eosim.{n}", o) for n, o in _public()]
    for name, obj in sources:
        for t in finder.find(obj, name):
            key = (t.docstring, t.lineno)
            if t.examples and key not in seen:
                seen.add(key)
                tests.append(t)
    return sorted(tests, key=lambda t: t.name)


DOCTESTS = _doctests()


@pytest.mark.parametrize("test", DOCTESTS, ids=[t.name for t in DOCTESTS])
def test_docstring_examples_run(test, tmp_path, monkeypatch):
    # From an empty folder: examples write only into their own temporary folders.
    monkeypatch.chdir(tmp_path)
    out = []
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    result = runner.run(test, out=out.append)
    assert result.failed == 0, "".join(out)
    assert not any(tmp_path.iterdir()), "a docstring example wrote into the current folder"


def test_doctests_are_found():
    names = {t.name.rsplit(".", 1)[-1] for t in DOCTESTS}
    for n in ("run", "load", "pics", "build_bundle", "open_bundle", "read_toml", "keys",
              "measure", "measures"):
        assert n in names, n


def _sections(doc: str) -> dict:
    """numpydoc sections of a docstring: ``{title: body}`` (titles underlined by dashes)."""
    lines = doc.splitlines()
    heads = [i for i in range(len(lines) - 1)
             if lines[i].strip() and re.fullmatch(r"-{3,}", lines[i + 1].strip())
             and len(lines[i + 1].strip()) == len(lines[i].strip())]
    out = {}
    for k, i in enumerate(heads):
        end = heads[k + 1] if k + 1 < len(heads) else len(lines)
        out[lines[i].strip()] = "\n".join(lines[i + 2:end])
    return out


def _check_callable(qualname, func, problems):
    doc = inspect.getdoc(func) or ""
    if not doc.strip():
        problems.append(f"{qualname}: no docstring")
        return
    sec = _sections(doc)
    params = [p for p in inspect.signature(func).parameters.values()
              if p.name not in ("self", "cls")]
    if params:
        if "Parameters" not in sec:
            problems.append(f"{qualname}: no Parameters section")
        else:
            for p in params:
                if not re.search(rf"^\s*{re.escape(p.name)}\s*:", sec["Parameters"], re.M):
                    problems.append(f"{qualname}: parameter `{p.name}` not documented")
    ret = inspect.signature(func).return_annotation
    if ret not in (None, "None") and "Returns" not in sec:
        problems.append(f"{qualname}: no Returns section")
    if ">>>" not in sec.get("Examples", ""):
        problems.append(f"{qualname}: no Examples section with a >>> line")


def _check_class(name, cls, problems):
    doc = inspect.getdoc(cls) or ""
    sec = _sections(doc)
    examples = sec.get("Examples", "")
    if ">>>" not in examples:
        problems.append(f"{name}: no Examples section with a >>> line")
    for member, value in vars(cls).items():
        if member.startswith("_"):
            continue
        q = f"{name}.{member}"
        if isinstance(value, property):
            if not (value.__doc__ or "").strip():
                problems.append(f"{q}: property without a docstring")
            if f".{member}" not in examples:
                problems.append(f"{q}: property not shown in {name}'s Examples")
        elif isinstance(value, (classmethod, staticmethod)):
            _check_callable(q, getattr(cls, member), problems)
        elif inspect.isfunction(value):
            _check_callable(q, value, problems)
    if is_dataclass(cls):
        attrs = sec.get("Attributes", "")
        for f in fields(cls):
            if not re.search(rf"^\s*{f.name}\s*:", attrs, re.M):
                problems.append(f"{name}: field `{f.name}` not in its Attributes section")


def test_every_public_object_is_documented():
    problems = []
    for name, obj in _public():
        if inspect.isclass(obj):
            _check_class(name, obj, problems)
        elif callable(obj):
            _check_callable(name, obj, problems)
    assert not problems, "undocumented public API:\n" + "\n".join(problems)


def test_docstrings_do_not_send_readers_to_repository_files():
    # The wheel ships no docs/ folder: the docstrings must stand on their own.
    for name, obj in _public():
        docs = [inspect.getdoc(obj) or ""]
        if inspect.isclass(obj):
            docs += [inspect.getdoc(v) or "" for k, v in vars(obj).items() if not k.startswith("_")]
        for d in docs:
            assert "docs/" not in d, f"{name}: its docstring points to docs/"


def test_the_checks_catch_an_undocumented_function():
    problems = []

    def documented_badly(x, y=1):
        """Something.

        Parameters
        ----------
        x : int
            A number.
        """
        return x

    _check_callable("documented_badly", documented_badly, problems)
    assert any("`y` not documented" in p for p in problems), problems
    assert any("no Returns" in p for p in problems), problems
    assert any("no Examples" in p for p in problems), problems
