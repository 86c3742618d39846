"""Griffe extension for the API reference: read the reST habits of spm-pin's docstrings.

The docstrings are Google style, but their prose borrows a few reStructuredText
constructs that Markdown does not know. Before mkdocstrings renders a docstring this
extension rewrites them, without touching the source files:

* roles such as ``:class:`~spm_pin.SPMDesign` `` or ``:meth:`project` `` become code
  that links to the object's API entry when that entry exists (an optional autoref);
* a paragraph ending in ``::`` ends in ``:`` (the indented block after it is already a
  Markdown code block), and a lone ``Example::`` becomes a bold title rather than a
  Google section;
* simple tables (columns under ``====  ====`` rules) become Markdown tables;
* module and class attributes documented by ``#:`` comments above them (the Sphinx
  convention) get those comments as their docstrings.

Loaded by mkdocs.yml (plugins > mkdocstrings > handlers > python > options > extensions).
"""

from __future__ import annotations

import html
import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(class|func|meth|attr|mod|data|obj|exc|const):`([^`]+)`")
EXPLICIT_TITLE = re.compile(r"^(.*?)\s*<([^<>]+)>$")
TABLE_RULE = re.compile(r"^(\s*)(=+)((?:\s+=+)+)\s*$")
#: Words that open a section of a Google-style docstring when followed by a colon.
GOOGLE_SECTIONS = frozenset(
    {
        "Args",
        "Arguments",
        "Attributes",
        "Classes",
        "Example",
        "Examples",
        "Functions",
        "Methods",
        "Modules",
        "Note",
        "Notes",
        "Other Parameters",
        "Parameters",
        "Raises",
        "Receives",
        "Returns",
        "See Also",
        "Warning",
        "Warnings",
        "Warns",
        "Yields",
    }
)


class ReSTProse(griffe.Extension):
    """Rewrite reST roles, literal-block markers and simple tables as Markdown."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        """Rewrite every docstring of the package once it is fully loaded."""
        for obj in _walk(pkg):
            if obj.is_attribute and obj.docstring is None:
                _comment_docstring(obj)
            if obj.docstring is not None:
                obj.docstring.value = markdown_from_rest(obj.docstring.value, obj)


def _walk(obj: griffe.Object) -> list[griffe.Object]:
    found = [obj]
    for member in obj.members.values():
        if not member.is_alias:
            found.extend(_walk(member))  # type: ignore[arg-type]
    return found


def _comment_docstring(attribute: griffe.Object) -> None:
    """Give ``attribute`` the ``#:`` comment lines right above it as its docstring."""
    lines = attribute.module.lines
    if attribute.lineno is None or not lines:
        return
    comment: list[str] = []
    index = attribute.lineno - 2
    while index >= 0 and lines[index].lstrip().startswith("#:"):
        comment.insert(0, lines[index].lstrip()[2:].strip())
        index -= 1
    if comment:
        attribute.docstring = griffe.Docstring(
            "\n".join(comment), lineno=index + 2, endlineno=attribute.lineno - 1, parent=attribute
        )


def markdown_from_rest(text: str, obj: griffe.Object) -> str:
    """The docstring ``text`` of ``obj`` with its reST constructs in Markdown."""
    text = _tables(text)
    text = ROLE.sub(lambda match: _role(match, obj), text)
    return _literal_markers(text)


def _role(match: re.Match[str], obj: griffe.Object) -> str:
    target = match.group(2).strip()
    explicit = EXPLICIT_TITLE.match(target)
    if explicit:
        title, target = explicit.group(1), explicit.group(2)
    else:
        title = target.lstrip("~.")
        if target.startswith("~"):
            title = title.rsplit(".", 1)[-1]
    if match.group(1) in ("func", "meth") and not title.endswith(")"):
        title += "()"
    code = f"<code>{html.escape(title)}</code>"
    path = _resolve(target.lstrip("~"), obj)
    if path is None:
        return code
    return f'<autoref identifier="{path}" optional>{code}</autoref>'


def _resolve(target: str, obj: griffe.Object) -> str | None:
    """The canonical path of ``target`` seen from ``obj``, or None."""
    if target.startswith("."):
        package = obj.module if obj.module.is_package else obj.module.parent
        candidates = [f"{package.path}{target}"] if package is not None else []
    else:
        candidates = [target]
        scope: griffe.Object | None = obj
        while scope is not None:
            candidates.append(f"{scope.path}.{target}")
            scope = scope.parent
        first, _, rest = target.partition(".")
        try:
            resolved = obj.resolve(first)
        except (griffe.NameResolutionError, ValueError, AttributeError):
            resolved = None
        if resolved:
            candidates.append(f"{resolved}.{rest}" if rest else resolved)
    for candidate in candidates:
        try:
            found = obj.modules_collection.get_member(candidate)
        except (KeyError, ValueError, griffe.AliasResolutionError, griffe.CyclicAliasError):
            continue
        try:
            found = found.final_target if found.is_alias else found
        except (griffe.AliasResolutionError, griffe.CyclicAliasError):
            continue
        return _unshadowed(found).path
    return None


def _unshadowed(obj: griffe.Object) -> griffe.Object:
    """The function a package imports over its submodule of the same name.

    ``from .jacobian import jacobian`` in ``spm_pin/kinematics/__init__.py`` makes
    ``spm_pin.kinematics.jacobian`` the function at run time, but griffe keeps the
    submodule under that name; the function is what the docstrings mean.
    """
    if obj.is_module and obj.name in obj.members and not obj.members[obj.name].is_alias:
        return obj.members[obj.name]  # type: ignore[return-value]
    return obj


def _literal_markers(text: str) -> str:
    lines = text.split("\n")
    for index, line in enumerate(lines):
        stripped = line.rstrip()
        if stripped.endswith("::") and not stripped.endswith(":::"):
            before = stripped[:-2].rstrip()
            if before.strip() in GOOGLE_SECTIONS:  # "Example::" is no Google section
                indent = before[: len(before) - len(before.lstrip())]
                lines[index] = f"{indent}**{before.strip()}**"
            else:
                lines[index] = before + ":" if before else ""
    return "\n".join(lines)


def _tables(text: str) -> str:
    lines = text.split("\n")
    out: list[str] = []
    index = 0
    while index < len(lines):
        rule = TABLE_RULE.match(lines[index])
        if not rule:
            out.append(lines[index])
            index += 1
            continue
        end = index + 1
        rules = [index]
        while end < len(lines) and lines[end].strip():
            if TABLE_RULE.match(lines[end]):
                rules.append(end)
            end += 1
        if len(rules) < 2:
            out.append(lines[index])
            index += 1
            continue
        out.extend(_table(lines[index : rules[-1] + 1], lines[index]))
        index = rules[-1] + 1
    return "\n".join(out)


def _table(block: list[str], rule_line: str) -> list[str]:
    spans = [match.span() for match in re.finditer(r"=+", rule_line)]
    indent = TABLE_RULE.match(rule_line).group(1)  # type: ignore[union-attr]
    sections: list[list[list[str]]] = [[]]
    for line in block[1:]:
        if TABLE_RULE.match(line):
            sections.append([])
            continue
        cells = []
        for number, (start, stop) in enumerate(spans):
            stop = len(line) if number == len(spans) - 1 else spans[number + 1][0]
            cells.append(line[start:stop].strip())
        rows = sections[-1]
        if rows and not cells[0]:  # a continuation line of the row above
            rows[-1] = [f"{a} {b}".strip() for a, b in zip(rows[-1], cells, strict=True)]
        else:
            rows.append(cells)
    sections = [section for section in sections if section]
    if len(sections) >= 2:
        header, body = sections[0], [row for section in sections[1:] for row in section]
    else:
        header, body = [[""] * len(spans)], sections[0] if sections else []
    table = [indent + "| " + " | ".join(header[0]) + " |"]
    table.append(indent + "|" + "|".join(" --- " for _ in spans) + "|")
    table.extend(indent + "| " + " | ".join(row) + " |" for row in header[1:] + body)
    return ["", *table, ""]
