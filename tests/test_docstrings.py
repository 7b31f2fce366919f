"""Every public function documents every parameter (STYLE.md: numpydoc, enforced by a test)."""

import importlib
import inspect
import pkgutil
import re

import driveid


def _public_callables():
    for info in pkgutil.walk_packages(driveid.__path__, "driveid."):
        if info.name.startswith("driveid.commands") or info.name == "driveid.cli":
            continue  # click commands document options in their --help instead
        module = importlib.import_module(info.name)
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if inspect.isfunction(obj) and obj.__module__ == module.__name__:
                yield f"{info.name}.{name}", obj


def _documented(doc: str) -> set[str]:
    section = re.split(r"\n\s*Parameters\n\s*-+\n", doc, maxsplit=1)
    if len(section) < 2:
        return set()
    body = re.split(r"\n\s*(Returns|Yields|Raises|Warns|Notes|Examples|See Also|References)"
                    r"\n\s*-+\n", section[1], maxsplit=1)[0]
    names = set()
    for line in body.splitlines():
        match = re.match(r"^\s{4}(\*{0,2}[\w, *]+?)\s*(:|$)", line)
        if match and not line.startswith("        "):
            names.update(n.strip().lstrip("*") for n in match.group(1).split(","))
    return names


def test_every_public_parameter_is_documented():
    missing = []
    for qualname, func in _public_callables():
        params = [p for p in inspect.signature(func).parameters if p not in ("self", "cls")]
        if not params:
            continue
        documented = _documented(inspect.getdoc(func) and func.__doc__ or "")
        absent = [p for p in params if p not in documented]
        if absent:
            missing.append(f"{qualname}: {absent}")
    assert not missing, "undocumented parameters:\n" + "\n".join(missing)
