"""``eosim.keys``: the documented keys of the experiment file, read from the reference that
ships inside the package (``eosim/data/experiment.md``, a byte-for-byte copy of the
repository's ``docs/experiment.md``; ``scripts/sync-python-docs.sh`` refreshes it and a test
fails when the two differ). The key tables are parsed from that text when first asked for, so
the Python help and the documentation cannot drift apart.

How tables get their section names (``_parse``):

* a ``## `[name]` `` or ``## `[[name]]` `` heading starts section ``name``; another ``##``
  heading starts a section named by its words (``## Top level``: ``top_level``);
* a table introduced by a paragraph that starts with ``` `type = "X"` ``` is ``SECTION.X``
  (``measures.ortho``), one introduced by ``` `key` (...) ``` or ``` `key`: ``` is
  ``SECTION.key`` (``atmosphere.particle_layers``);
* otherwise a table under a ``###`` heading is ``SECTION.X`` when the heading holds
  ``type = "X"`` (``### Lidar (type = "lidar")``), else ``SECTION.words_of_the_heading``
  (``atmosphere.phase_tables``); a table under the ``##`` heading alone is ``SECTION``.

Only tables whose first column is ``key`` or ``type`` are keys; tables of file layouts
(``variable | dimensions | ...``) are left out.
"""

from __future__ import annotations

import difflib
import functools
import re
import textwrap
from importlib import resources
from typing import Optional

# The columns of a key table; a table without one of them (``[integrator]`` has no unit
# column) gives None there, so that every key record has the same fields.
_KEY_FIELDS = ("key", "type", "unit", "default", "meaning")

_TABLE_NAME = re.compile(r"`\[\[?([A-Za-z0-9_.]+)\]\]?`")
_TYPE_IS = re.compile(r'`type = "([A-Za-z0-9_]+)"`')
_KEY_FIRST = re.compile(r"`([A-Za-z0-9_]+)`(?=[\s(:])")
_SEPARATOR = re.compile(r"\|(\s*:?-+:?\s*\|)+")
_PIPE = re.compile(r"(?<!\\)\|")


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def _clean(cell: str) -> str:
    """A markdown cell as plain text: no backticks or bold marks, escaped pipes restored,
    whitespace collapsed."""
    cell = cell.replace("\\|", "|").replace("`", "").replace("**", "")
    return " ".join(cell.split())


def _cells(line: str) -> list:
    parts = _PIPE.split(line.strip())
    return [_clean(p) for p in parts[1:-1]]


def _first_sentence(text: str) -> str:
    text = _clean(text)
    m = re.search(r"(?<=\.)\s+(?=[A-Z])", text)
    s = text[: m.start()] if m else text
    return s.rstrip(":")


class _Section:
    def __init__(self, name, heading, summary, columns):
        self.name, self.heading, self.summary, self.columns = name, heading, summary, columns
        self.rows: list = []


def _parse(text: str):
    """``({name: _Section}, problems)`` of the reference text; ``problems`` lists what breaks
    the rules above (a table row block without a header, rows of the wrong width, one name for
    tables of different columns): the package's tests require none."""
    sections: dict = {}
    problems: list = []
    h2 = h2_title = None
    h3_title = None
    para: list = []  # the paragraph being read
    last = ""  # the last paragraph since the last heading or table
    fence = False
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.lstrip().startswith("```"):
            fence = not fence
            para = []
            i += 1
            continue
        if fence:
            i += 1
            continue
        if line.startswith("## ") or line.startswith("### "):
            title = line.lstrip("#").strip()
            if line.startswith("## "):
                m = _TABLE_NAME.search(title)
                h2, h2_title, h3_title = (m.group(1) if m else _slug(title)), title, None
            else:
                h3_title = title
            para, last = [], ""
            i += 1
            continue
        if not line.startswith("|"):
            if line.strip():
                para.append(line.strip())
            elif para:
                last, para = " ".join(para), []
            i += 1
            continue
        start = i
        block = []
        while i < len(lines) and lines[i].startswith("|"):
            block.append(lines[i])
            i += 1
        if para:
            last, para = " ".join(para), []
        if h2 is None:
            last = ""
            continue
        if len(block) < 2 or not _SEPARATOR.fullmatch(block[1].strip()):
            problems.append(f"line {start + 1}: table rows without a header row and a |---| line "
                            "(a blank line inside a table?)")
            last = ""
            continue
        header = _cells(block[0])
        kind = header[0].lower() if header else ""
        if kind not in ("key", "type"):
            last = ""
            continue
        name, heading = _name(h2, h2_title, h3_title, last)
        columns = [_slug(h) or "notes" for h in header]
        if kind == "key":
            columns_out = list(_KEY_FIELDS) + [c for c in columns if c not in _KEY_FIELDS]
        else:
            columns_out = columns
        sec = sections.get(name)
        if sec is None:
            if last:
                summary = _first_sentence(last)
            else:
                summary = _clean(heading)
                summary = f"the {summary} table" if summary.startswith("[") else summary
            sec = sections[name] = _Section(name, _clean(heading), summary, columns_out)
        elif sec.columns != columns_out:
            problems.append(f"line {start + 1}: section {name!r} already has a table with the "
                            f"columns {sec.columns}, this one has {columns_out}")
        for k, row in enumerate(block[2:]):
            cells = _cells(row)
            if len(cells) != len(columns):
                problems.append(f"line {start + 3 + k}: {len(cells)} cells in a table of "
                                f"{len(columns)} columns")
                cells = (cells + [""] * len(columns))[: len(columns)]
            if not cells[0] and sec.rows:
                # A continuation row (more keys of the type above: the radiometry solvers).
                cells[0] = sec.rows[-1][columns[0]]
            rec = dict(zip(columns, cells))
            sec.rows.append({c: rec.get(c) for c in columns_out})
        last = ""
    return sections, problems


def _name(h2: str, h2_title: str, h3_title: Optional[str], para: str):
    """The section name of a table and the heading it sits under (rules: module docstring)."""
    m = _TYPE_IS.match(para)
    if m:
        return f"{h2}.{m.group(1)}", h3_title or h2_title
    m = _KEY_FIRST.match(para)
    if m and "=" not in m.group(0):
        return f"{h2}.{m.group(1)}", h3_title or h2_title
    if h3_title is not None:
        m = _TYPE_IS.search(h3_title)
        return f"{h2}.{m.group(1) if m else _slug(h3_title)}", h3_title
    return h2, h2_title


@functools.lru_cache(maxsize=1)
def _reference():
    text = resources.files(__package__).joinpath("data").joinpath("experiment.md").read_text(
        encoding="utf-8")
    return _parse(text)


class KeyTable(list):
    """The rows of one table of the experiment file as a list of dicts, shown as a readable
    table at the prompt (``repr``) and as a markdown table in Jupyter.

    ``section`` is the table's name (``"spectral"``, ``"measures.ortho"``, or ``"sections"``
    for the list of sections), ``summary`` one line saying what it holds, ``columns`` the
    fields of every row.
    """

    def __init__(self, rows, section: str, summary: str, columns):
        super().__init__(rows)
        self.section = section
        self.summary = summary
        self.columns = list(columns)

    def __repr__(self) -> str:
        head = f"{self.section}: {self.summary}" if self.summary else self.section
        out = [head]
        if self.section == "sections" or self.columns[:1] == ["section"]:
            width = max([len(r["section"]) for r in self] + [8])
            for r in self:
                out.append(f"  {r['section']:<{width}}  {r['keys']:>3} keys  {_short(r['summary'], 70)}")
            return "\n".join(out)
        first, middle, last = self.columns[0], self.columns[1:-1], self.columns[-1]
        for r in self:
            extras = []
            for c in middle:
                v = r.get(c)
                if v in (None, "", "—"):
                    continue
                extras.append(v if c == "type" and first == "key" else f"{c.replace('_', ' ')} {v}")
            out.append(f"  {r[first]}" + (f" ({'; '.join(extras)})" if extras else ""))
            if r.get(last):
                out.extend(textwrap.wrap(r[last], width=92, initial_indent="      ",
                                         subsequent_indent="      "))
        if not self:
            out.append("  (no keys)")
        return "\n".join(out)

    __str__ = __repr__

    def _repr_markdown_(self) -> str:
        def cell(v):
            return "" if v is None else str(v).replace("|", "\\|")

        out = [f"**{self.section}**: {cell(self.summary)}", "",
               "| " + " | ".join(self.columns) + " |",
               "|" + "---|" * len(self.columns)]
        out += ["| " + " | ".join(cell(r.get(c)) for c in self.columns) + " |" for r in self]
        return "\n".join(out)


def _short(text: str, n: int) -> str:
    return text if len(text) <= n else text[: n - 1].rstrip() + "…"


def _listing(sections, names, title, summary) -> KeyTable:
    rows = [{"section": n, "keys": len(sections[n].rows), "summary": sections[n].summary}
            for n in names]
    return KeyTable(rows, title, summary, ["section", "keys", "summary"])


def keys(section: Optional[str] = None) -> KeyTable:
    """The documented keys of one section of the experiment file.

    Each key comes with its type, unit, default and meaning, as the experiment-file reference
    gives them (the package carries a copy of it, so this works in any installation). Use it
    at the prompt to recall a key's spelling, unit or default before writing an experiment as
    a dict or a TOML file.

    Parameters
    ----------
    section : str, optional
        The section: a table of the file (``"spectral"``, ``"illumination"``,
        ``"integrator"``, ``"top_level"`` for the keys outside any table), a measure type
        (``"measures.ortho"``, ``"measures.lidar"``; ``"measures"`` holds the keys common to
        every measure), an atmosphere or scene type (``"atmosphere.molecular"``,
        ``"scene.bundle"``), and a few more (``"atmosphere.particle_layers"``,
        ``"atmosphere.phase_tables"``, ``"scene.radiometry_solvers"``). TOML brackets are
        accepted (``"[spectral]"``, ``"[[measures]]"``) and case is ignored. A name that only
        groups sections (``"atmosphere"``, ``"scene"``) lists them. None (the default) lists
        every section.

    Returns
    -------
    KeyTable
        A ``list`` of ``dict``, one per row of the table, shown as a readable table at the
        prompt (``print`` gives the same text; Jupyter shows a markdown table). Key tables
        have the fields ``key``, ``type``, ``unit``, ``default`` and ``meaning`` (strings as
        the reference writes them: ``"—"`` for no unit or no default, ``None`` where the
        table has no such column). The tables of types (``"surface"``: the BRDF models,
        ``"atmosphere.phase_tables"``, ``"scene.radiometry_solvers"``) have the fields
        ``type``, ``keys``, ... instead. The list of sections has ``section``, ``keys`` (how
        many rows) and ``summary``. The list's ``section``, ``summary`` and ``columns``
        attributes name it, say what it holds and give its fields.

    Raises
    ------
    TypeError
        If `section` is not a string (or None).
    ValueError
        If there is no such section; the message suggests the closest names (a misspelt
        measure type: ``"measures.orto"`` suggests ``"measures.ortho"``) and lists every
        section.

    See Also
    --------
    load : Validate an experiment; its errors name the offending key path.
    read_toml : Read an experiment file into a dict, to change a few keys.

    Examples
    --------
    >>> import eosim
    >>> spectral = eosim.keys("spectral")
    >>> wavelengths = [k for k in spectral if k["key"] == "wavelengths"][0]
    >>> wavelengths["unit"]
    'nm'
    >>> eosim.keys("measures.ortho")  # doctest: +ELLIPSIS
    measures.ortho: type = "ortho" (3D scenes): a north-up image of the scene seen from one direction (parallel projection).
      pixel_size_m (number > 0; unit m; default required)
          pixel size
    ...
    >>> "measures.lidar" in [s["section"] for s in eosim.keys()]
    True
    >>> try:
    ...     eosim.keys("measures.orto")
    ... except ValueError as e:
    ...     print(str(e).split(" Sections:")[0])
    eosim.keys: unknown section 'measures.orto'; did you mean 'measures.ortho'?
    """
    sections, _ = _reference()
    if section is None:
        return _listing(sections, list(sections), "sections",
                        "the sections of the experiment file; eosim.keys(NAME) gives one")
    if not isinstance(section, str):
        raise TypeError(f"section must be a string such as 'spectral' or 'measures.ortho', "
                        f"not {type(section).__name__}")
    q = section.strip().strip("[]").strip().lower()
    if q in sections:
        s = sections[q]
        return KeyTable([dict(r) for r in s.rows], s.name, s.summary, s.columns)
    inside = [n for n in sections if n.startswith(q + ".")]
    if q and inside:
        return _listing(sections, inside, q, f"the sections of [{q}]; eosim.keys(NAME) gives one")
    close = _suggest(q, list(sections))
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else "."
    raise ValueError(f"eosim.keys: unknown section {section!r}{hint} Sections: "
                     f"{', '.join(sections)}")


def _suggest(q: str, names: list) -> list:
    """The names closest to a misspelt section ``q``: for ``prefix.tail``, the prefix's
    sections whose last part is close to ``tail`` or begins with it (a misspelt prefix is
    corrected first); for a bare name, close names, groups and last parts (``"orto"``:
    ``measures.ortho``)."""
    prefixes = sorted({n.rsplit(".", 1)[0] for n in names if "." in n})
    groups = [g for g in prefixes if g not in names]
    if "." in q:
        prefix, tail = q.rsplit(".", 1)
        if prefix not in prefixes:
            fixed = difflib.get_close_matches(prefix, prefixes, n=1, cutoff=0.6)
            if not fixed:
                return difflib.get_close_matches(q, names, n=3, cutoff=0.6)
            prefix = fixed[0]
        subs = {n.rsplit(".", 1)[1]: n for n in names if n.startswith(prefix + ".")}
        close = difflib.get_close_matches(tail, list(subs), n=3, cutoff=0.6)
        close += [t for t in subs if tail and (t.startswith(tail) or tail in t.split("_"))
                  and t not in close]
        return [subs[t] for t in close][:3]
    out = difflib.get_close_matches(q, names + groups, n=3, cutoff=0.6)
    tails = {n.rsplit(".", 1)[1]: n for n in names if "." in n}
    out += [tails[t] for t in difflib.get_close_matches(q, list(tails), n=3, cutoff=0.6)
            if tails[t] not in out]
    return out[:3]
