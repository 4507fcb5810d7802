"""Digests of the code behind a value: a function's syntax tree and those of everything of the
analysis package it names, transitively.

:func:`closure` collects, from a function (or class), the *units* it can reach: functions and
classes of ``tiltpile.analysis`` named in its body, its decorators or its default values (by a
global name, an attribute of a module of the package such as ``_ct.bulk_coordination``, or a
name imported inside the function), and the package's module-level constants it names (their
values). It follows each unit's own names in turn. numba dispatchers are followed to their
Python function, ``functools`` wrappers to the wrapped one. Code outside the package (numpy,
scipy, pandas, the run-file reader :mod:`tiltpile.store`) is not followed: the environment and
the run-file format are outside the digests.

A unit's text is its syntax tree without docstrings (comments are not in it), a constant's its
value, so that editing a docstring, a comment or a function the code does not reach keeps the
digest, and editing anything it reaches changes it. A name is followed wherever it appears, also
where a local variable shadows it: the closure may hold more than the code can run, never less.

Names listed in ``skip`` (``"module:NAME"``) are not followed: declarations that decide only
which values exist and in what order (the tables' column lists), never a value.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib
import inspect
import sys
import textwrap
import types

import numpy as np

PACKAGE = "tiltpile.analysis"


def _ours(obj) -> bool:
    mod = getattr(obj, "__module__", None) or ""
    return mod == PACKAGE or mod.startswith(PACKAGE + ".")


def _unwrap(obj):
    """The Python function behind a numba dispatcher, an lru_cache or a functools.wraps."""
    for _ in range(10):
        if hasattr(obj, "py_func"):
            obj = obj.py_func
        elif isinstance(obj, functools.partial):
            return obj
        elif hasattr(obj, "__wrapped__") and callable(obj):
            obj = obj.__wrapped__
        else:
            return obj
    return obj


def _strip(tree: ast.AST) -> ast.AST:
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                node.body = body[1:] or [ast.Pass()]
    return tree


def code_only(source: str) -> str:
    """``source``'s syntax tree without docstrings (comments are not in it): what it computes."""
    return ast.dump(_strip(ast.parse(source)), annotate_fields=False, include_attributes=False)


def _key(obj) -> str:
    return f"{obj.__module__}:{obj.__qualname__}"


def _local_imports(tree: ast.AST, module: str) -> dict:
    """Names bound by import statements inside a unit: {alias: object} (package ones only)."""
    out = {}
    pkg = module.rsplit(".", 1)[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.rsplit(".", node.level - 1)[0] if node.level > 1 else pkg
                name = f"{base}.{node.module}" if node.module else base
            else:
                name = node.module or ""
            if not (name == PACKAGE or name.startswith(PACKAGE + ".")):
                continue
            mod = importlib.import_module(name)
            for a in node.names:
                if hasattr(mod, a.name):
                    out[a.asname or a.name] = getattr(mod, a.name)
                else:
                    out[a.asname or a.name] = importlib.import_module(f"{name}.{a.name}")
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name == PACKAGE or a.name.startswith(PACKAGE + "."):
                    out[a.asname or a.name.split(".")[0]] = importlib.import_module(a.name)
    return out


def _value_text(value, refs: list, where: str) -> str:
    """A constant's value as text; the functions and classes it holds go to ``refs``."""
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes)):
        return repr(value)
    if isinstance(value, (tuple, list)):
        inner = ", ".join(_value_text(v, refs, where) for v in value)
        return f"{type(value).__name__}({inner})"
    if isinstance(value, (set, frozenset)):
        inner = ", ".join(sorted(_value_text(v, refs, where) for v in value))
        return f"{type(value).__name__}({inner})"
    if isinstance(value, dict):
        inner = ", ".join(f"{_value_text(k, refs, where)}: {_value_text(v, refs, where)}"
                          for k, v in value.items())
        return f"dict({inner})"
    if isinstance(value, np.ndarray):
        a = np.ascontiguousarray(value)
        return f"ndarray({a.dtype.str}, {a.shape}, {hashlib.sha256(a.tobytes()).hexdigest()})"
    if isinstance(value, np.generic):
        return f"{type(value).__name__}({value!r})"
    u = _unwrap(value)
    if isinstance(u, (types.FunctionType, type)):
        if _ours(u):
            refs.append(u)
            return f"<{_key(u)}>"
        return f"<external {getattr(u, '__module__', '?')}.{getattr(u, '__qualname__', '?')}>"
    if isinstance(u, types.ModuleType) or callable(u):
        return f"<external {type(u).__name__}>"
    raise TypeError(f"{where}: cannot digest a {type(value).__name__} (give the value as plain "
                    "numbers, strings, containers, arrays, functions or classes)")


def closure(obj, skip=frozenset()) -> dict[str, str]:
    """The units ``obj`` reaches (module docstring): {key: text}, key ``module:qualname``."""
    todo, out = [_unwrap(obj)], {}
    while todo:
        u = _unwrap(todo.pop())
        if isinstance(u, functools.partial):
            refs: list = []
            text = _value_text((u.func, u.args, dict(u.keywords)), refs, "partial")
            out.setdefault(f"partial:{text}", text)
            todo.extend(refs)
            continue
        key = _key(u)
        if key in out:
            continue
        text, consts, refs = _unit(u, frozenset(skip))
        out[key] = text
        out.update(consts)
        todo.extend(r for r in refs if _key(_unwrap(r)) not in out)
    return out


@functools.lru_cache(maxsize=None)
def _unit(u, skip: frozenset) -> tuple[str, dict, tuple]:
    """One unit's text, the constants it names ({key: text}) and the units it names."""
    tree = _strip(ast.parse(textwrap.dedent(inspect.getsource(u))))
    text = ast.dump(tree, annotate_fields=False, include_attributes=False)
    module = u.__module__
    scope = vars(sys.modules[module])
    local = _local_imports(tree, module)
    consts, refs = {}, []

    def resolve(name):
        if name in local:
            return local[name], True
        if name in scope:
            return scope[name], f"{module}:{name}" not in skip
        return None, False

    def take(val, key, where):
        if isinstance(val, types.ModuleType):
            return
        uv = _unwrap(val)
        if isinstance(uv, (types.FunctionType, type)):
            if _ours(uv):
                refs.append(uv)
            return
        if callable(val) and not isinstance(val, functools.partial):
            return      # an external callable (np.add, a builtin re-bound, ...)
        consts[key] = _value_text(val, refs, where)

    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            val, ok = resolve(node.id)
            if ok:
                take(val, f"{module}:{node.id}=", f"{module}:{node.id}")
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            base, ok = resolve(node.value.id)
            if not ok or not isinstance(base, types.ModuleType) or not (
                    base.__name__ == PACKAGE or base.__name__.startswith(PACKAGE + ".")):
                continue
            if f"{base.__name__}:{node.attr}" in skip or not hasattr(base, node.attr):
                continue
            take(getattr(base, node.attr), f"{base.__name__}:{node.attr}=",
                 f"{base.__name__}:{node.attr}")
    return text, consts, tuple(refs)


def digest(parts) -> str:
    """16 hex digits of SHA-256 over ``parts`` (strings, or {key: text} dicts, sorted by key)."""
    h = hashlib.sha256()
    for p in parts:
        items = sorted(p.items()) if isinstance(p, dict) else [("", p)]
        for k, v in items:
            h.update(k.encode() + b"\0" + v.encode() + b"\0")
        h.update(b"\1")
    return h.hexdigest()[:16]
