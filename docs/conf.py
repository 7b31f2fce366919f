"""Sphinx configuration of the driveid documentation site.

Build (from the repository root, after ``pip install -e '.[docs]'``)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

Pages are Markdown (MyST). The API reference has one page per public module, written at
build time from the package itself into ``docs/api/generated/`` (git-ignored, like
autosummary's stubs), so a new module appears without editing the docs; each page is an
``automodule`` of the module's numpydoc docstrings.
"""

from __future__ import annotations

import logging
import os
import pkgutil
import re
import sys
import tempfile
from pathlib import Path

_DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(_DOCS.parent / "src"))  # a fresh clone builds without installing

import driveid  # noqa: E402

project = "driveid"
author = "driveid developers"
copyright = "driveid developers (MIT licence)"
release = version = driveid.__version__

extensions = ["sphinx.ext.autodoc", "numpydoc", "myst_parser"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "figures", "Thumbs.db", ".DS_Store"]
html_theme = "alabaster"
html_title = f"driveid {release}"

# MyST: heading anchors let pages link to sections ([text](page.md#a-section)).
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence", "deflist"]

# autodoc: members in source order; type hints in the signature only (the docstrings carry
# the types with units); members defined in the module itself, not its re-exports (those
# are documented on the page of the module that defines them).
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"members": True, "show-inheritance": True,
                           "ignore-module-all": True}

# numpydoc: render the sections; no member tables (they need autosummary stubs), no style
# validation here (ruff D and tests/test_docstrings.py enforce the docstring rules).
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()
numpydoc_xref_param_type = False

# A References section listed without an inline [1]_ citation is our docstring style (the
# thesis is cited by equation number in the text), not a broken reference.
suppress_warnings = ["ref.citation"]

#: Docstrings whose reStructuredText is known to be broken, reported to their owners; their
#: docutils messages are not turned into build errors. Remove an entry once it is fixed;
#: ``DRIVEID_DOCS_ALL_WARNINGS=1`` shows them.
KNOWN_DOCSTRING_ISSUES: dict[str, str] = {}  # all fixed at their source

_GENERATED = _DOCS / "api" / "generated"
_SKIP = ("driveid.commands", "driveid.cli")  # click commands: see `driveid COMMAND --help`


def public_modules() -> list[str]:
    """Return the public modules of driveid (no ``_private`` parts, no click commands)."""
    names = []
    for info in pkgutil.walk_packages(driveid.__path__, "driveid."):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        if not info.name.startswith(_SKIP):
            names.append(info.name)
    return sorted(names)


def _write_if_changed(path: Path, text: str) -> None:
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return  # unchanged: keeps Sphinx's incremental build and concurrent builds quiet
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    os.replace(tmp, path)


def _generate_api_pages(app) -> None:  # noqa: ANN001 - Sphinx event signature
    _GENERATED.mkdir(parents=True, exist_ok=True)
    modules = public_modules()
    for name in modules:
        _write_if_changed(_GENERATED / f"{name}.md",
                          f"# `{name}`\n\n```{{eval-rst}}\n.. automodule:: {name}\n```\n")
    for stale in _GENERATED.glob("*.md"):
        if stale.stem not in modules:
            stale.unlink(missing_ok=True)


_BARS = re.compile(r"(?<![\\|`\w])\|([^|\s`][^|`\n]*?)\|(?![_|`\w])")
_INLINE_CODE = re.compile(r"(``.+?``|`[^`]+`)")
_UNDERLINE = re.compile(r"^(\s*)([-=~^])\2{2,}\s*$")


def _plain_text_docstring(app, what, name, obj, options, lines):  # noqa: ANN001
    """Keep plain-text habits of our docstrings from breaking reStructuredText.

    ``|x|`` (absolute value) would be a substitution reference: its bars are escaped,
    except in math and literal blocks. A section underline shorter than its title (titles
    with non-ASCII symbols) is lengthened. A module's References section becomes a rubric.
    """
    literal_indent = None
    for i, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if literal_indent is not None:
            if stripped and indent <= literal_indent:
                literal_indent = None
            else:
                continue
        if stripped.endswith("::") or stripped.startswith(".. math"):
            literal_indent = indent
        if stripped.startswith("|"):
            continue  # a line block or a table row
        parts = _INLINE_CODE.split(line)  # odd parts are ``literal`` or `role` text
        lines[i] = "".join(p if k % 2 else _BARS.sub(r"\\|\1\\|", p)
                           for k, p in enumerate(parts))
        if stripped.rstrip() == "References" and i + 1 < len(lines) and re.fullmatch(
                r"\s*-{3,}\s*", lines[i + 1]):
            # a module's References section would be a page section labelled "references",
            # the same label on every module page: make it a rubric (as numpydoc does)
            lines[i], lines[i + 1] = " " * indent + ".. rubric:: References", ""
            continue
        match = _UNDERLINE.match(line)
        if match and i > 0 and lines[i - 1].strip() and len(line.rstrip()) < len(
                lines[i - 1].rstrip()):
            lines[i] = match.group(1) + match.group(2) * (
                len(lines[i - 1].rstrip()) - len(match.group(1)))


class _KnownIssues(logging.Filter):
    """Let the docutils messages of :data:`KNOWN_DOCSTRING_ISSUES` through as info only."""

    seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno < logging.WARNING:
            return True
        where = f"{getattr(record, 'location', '')} {record.getMessage()}"
        for name in KNOWN_DOCSTRING_ISSUES:
            if re.search(rf"docstring of {re.escape(name)}(?![\w.])", where):
                self.seen.add(name)
                return False
        return True


def _install_filter(app) -> None:  # noqa: ANN001 - Sphinx event signature
    if os.environ.get("DRIVEID_DOCS_ALL_WARNINGS"):
        return  # show the known issues too (for their owners)
    for handler in logging.getLogger("sphinx").handlers:
        handler.filters.insert(0, _KnownIssues())


def setup(app):  # noqa: ANN001 - Sphinx hook
    """Generate the API pages and register the docstring hooks."""
    app.connect("builder-inited", _generate_api_pages)
    app.connect("builder-inited", _install_filter)
    app.connect("autodoc-process-docstring", _plain_text_docstring)
    return {"parallel_read_safe": True}
