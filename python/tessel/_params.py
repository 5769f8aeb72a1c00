"""Keyword parameters <-> the library's params structs, structs -> dicts.

The names are the C fields' (include/tessel.h), the defaults come from the
library's tessel_*_params_default() functions, and the field list from the
generated _abi.FIELDS: a field added to a params struct in tessel.h is a
keyword parameter at the next build, with its default and its comment.

Addressing a field of a nested struct:
  - by its own name when that is unambiguous among the fields in scope
    (mu=2.5 is greedy.mu);
  - by a path with double underscores (smooth__front__k=20), as sklearn does;
  - by a dict for the nested struct (smooth={"front": {"k": 20}}).
Unknown or ambiguous names raise TypeError naming the candidates.
"""
import ctypes
import difflib
import functools
import numbers
from collections.abc import Mapping

from . import _abi, _lib

FIELDS = _abi.FIELDS


def default(struct_name):
    """The struct tessel_<...>_default() returns (a ctypes Structure)."""
    return getattr(_lib.lib, struct_name + "_default")()


def _short_names(enum_type):
    """Enumerators without their common prefix, lower case: TESSEL_VIEW_ISO -> iso."""
    items = [(n, v) for n, v, _ in _abi.ENUMS[enum_type] if not n.endswith("_COUNT")]
    names = [n for n, _ in items]
    prefix = names[0]
    for n in names[1:]:
        while not n.startswith(prefix):
            prefix = prefix[:-1]
    prefix = prefix[:prefix.rfind("_") + 1] if len(names) > 1 else names[0].rsplit("_", 1)[0] + "_"
    return {n[len(prefix):].lower(): v for n, v in items}


ENUM_NAMES = {t: _short_names(t) for t in _abi.ENUMS}
ENUM_BY_VALUE = {t: {v: k for k, v in names.items()} for t, names in ENUM_NAMES.items()}


def enum_value(enum_type, value, what):
    """An enumerator from its short name ("iso"), its C name or its value."""
    names = ENUM_NAMES[enum_type]
    if isinstance(value, str):
        key = value.strip().lower().replace("-", "_")
        if key in names:
            return names[key]
        for n, v, _ in _abi.ENUMS[enum_type]:
            if value == n:
                return v
        raise _lib.InvalidArgumentError(
            "%s must be one of %s, got %r" % (what, ", ".join(repr(k) for k in names), value))
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        if int(value) in names.values():
            return int(value)
        raise _lib.InvalidArgumentError("%s: %d is not a valid %s" % (what, value, enum_type))
    raise TypeError("%s must be a string (one of %s), got %r"
                    % (what, ", ".join(repr(k) for k in names), value))


def enum_name(enum_type, value):
    return ENUM_BY_VALUE[enum_type].get(int(value), int(value))


def _int_range(ctype):
    bits = 8 * ctypes.sizeof(ctype)
    if ctype(-1).value < 0:
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return 0, (1 << bits) - 1


def _scalar(value, ctype, what):
    if ctype in (ctypes.c_float, ctypes.c_double):
        if isinstance(value, numbers.Real) and not isinstance(value, bool):
            return float(value)
        raise TypeError("%s must be a number, got %r" % (what, value))
    if isinstance(value, numbers.Integral):
        lo, hi = _int_range(ctype)
        v = int(value)
        if not lo <= v <= hi:
            raise _lib.InvalidArgumentError("%s must be in [%d, %d], got %d" % (what, lo, hi, v))
        return v
    raise TypeError("%s must be an integer%s, got %r"
                    % (what, " (or a bool)" if _int_range(ctype) == _int_range(ctypes.c_int)
                       else "", value))


def field_types(struct_name):
    cls = _abi.STRUCTS[struct_name]
    return dict(cls._fields_)


def leaves(struct_name, prefix=()):
    """[(path, kind, C type, array length, comment)] of every settable leaf
    (pointers and function pointers are not)."""
    out = []
    pointers = {f[0] for f in FIELDS[struct_name] if f[1] == "pointer"}
    for name, kind, ctype, n, doc in FIELDS[struct_name]:
        path = prefix + (name,)
        if name.endswith("_count") and name[:-len("_count")] in pointers:
            continue  # the length of an array that cannot be set from Python
        if kind == "struct":
            out.extend(leaves(ctype, path))
        elif kind in ("scalar", "enum"):
            out.append((path, kind, ctype, n, doc))
    return out


@functools.lru_cache(maxsize=None)
def _node_paths(struct_name, prefix=()):
    """Paths of every settable leaf and every nested struct."""
    out = []
    for name, kind, ctype, _, _ in FIELDS[struct_name]:
        if kind == "struct":
            out.append(prefix + (name,))
            out.extend(_node_paths(ctype, prefix + (name,)))
    out.extend(l[0] for l in leaves(struct_name, prefix) if len(l[0]) == len(prefix) + 1)
    return tuple(out)


@functools.lru_cache(maxsize=None)
def _leaf_paths(struct_name):
    return frozenset(l[0] for l in leaves(struct_name))


def _field(struct_name, name):
    for f in FIELDS[struct_name]:
        if f[0] == name:
            return f
    return None


def _resolve_path(struct_name, path, key):
    """The fields along path, checked; returns the last field's entry."""
    sname = struct_name
    entry = None
    for i, name in enumerate(path):
        if sname is None:
            raise TypeError("unexpected keyword argument %r: %s is not a struct"
                            % (key, "__".join(path[:i])))
        entry = _field(sname, name)
        if entry is None:
            raise TypeError("unexpected keyword argument %r: %s has no field %r%s"
                            % (key, sname, name, _suggest(name, [f[0] for f in FIELDS[sname]])))
        sname = entry[2] if entry[1] == "struct" else None
    return entry


def _suggest(name, names):
    close = difflib.get_close_matches(name, names, n=3, cutoff=0.6)
    return (" (did you mean %s?)" % ", ".join(close)) if close else ""


def _expand(struct_name, path, value, key, out):
    """A value for path: a dict for a nested struct becomes its leaves."""
    entry = _resolve_path(struct_name, path, key) if path else None
    if entry is not None and entry[1] == "struct":
        if not isinstance(value, Mapping):
            raise TypeError("%s must be a dict of %s fields, got %r" % (key, entry[2], value))
        for k, v in value.items():
            _expand(struct_name, path + (k,), v, "%s[%r]" % (key, k), out)
        return
    if entry[1] in ("pointer", "funcptr") or path not in _leaf_paths(struct_name):
        raise TypeError("%s (%s) cannot be set from Python" % (key, "__".join(path)))
    if path in out:
        raise TypeError("%s given twice" % "__".join(path))
    out[path] = value


def resolve(struct_name, kwargs, scopes=None):
    """kwargs -> {path: value}. scopes: the nested structs (path prefixes)
    whose fields may be named alone; None: the whole struct."""
    out = {}
    nodes = _node_paths(struct_name)
    top = [f[0] for f in FIELDS[struct_name]]
    for key, value in kwargs.items():
        parts = tuple(key.split("__"))
        if parts[0] in top:
            path = parts  # from the root: checked by _expand
        else:
            # A name or a path's tail, within the scopes: mu, front__k.
            n = len(parts)
            cands = [p for p in nodes if p[-n:] == parts and
                     (scopes is None or any(p[:len(s)] == s for s in scopes))]
            if len(cands) > 1:
                raise TypeError("keyword argument %r is ambiguous: give one of %s"
                                % (key, ", ".join("__".join(p) for p in cands)))
            if not cands:
                names = sorted(set(top) | {p[-1] for p in nodes} |
                               {"__".join(p) for p in nodes})
                raise TypeError("unexpected keyword argument %r%s" % (key, _suggest(key, names)))
            path = cands[0]
        _expand(struct_name, path, value, key, out)
    # Setting X sets the switch that makes the library use it, as the
    # command line does: use_X to 1 (viewpoint -> use_viewpoint), X_from_...
    # to 0 (mu -> mu_from_sampling), unless the switch is given too.
    for path in list(out):
        parent = path[:-1]
        sname = struct_name
        for name in parent:
            sname = _field(sname, name)[2]
        for f in FIELDS[sname]:
            switch = parent + (f[0],)
            if switch in out or f[1] != "scalar":
                continue
            if f[0] == "use_" + path[-1]:
                out[switch] = 1
            elif f[0].startswith(path[-1] + "_from_"):
                out[switch] = 0
        # Switches whose names do not say what they switch (the command
        # line sets them the same way).
        sname = struct_name
        for i in range(len(path)):
            rule = _SWITCHES.get((sname, path[i:]))
            if rule and path[:i] + (rule[0],) not in out:
                out[path[:i] + (rule[0],)] = rule[1]
            entry = _field(sname, path[i])
            if entry is None or entry[1] != "struct":
                break
            sname = entry[2]
    return out


# (struct, path of a field inside it) -> (field of the struct to set, value).
_SWITCHES = {
    ("tessel_smooth_recon_params", ("simplify", "cluster", "max_diameter")):
        ("auto_cluster_size", 0),
}


def assign(struct, struct_name, resolved):
    """Writes {path: value} into a ctypes struct of type struct_name."""
    for path, value in resolved.items():
        obj, sname = struct, struct_name
        for name in path[:-1]:
            obj = getattr(obj, name)
            sname = _field(sname, name)[2]
        name = path[-1]
        _, kind, ctype_name, n, _ = _field(sname, name)
        what = "__".join(path)
        ctype = field_types(sname)[name]
        if kind == "enum":
            setattr(obj, name, enum_value(ctype_name, value, what))
        elif n:
            try:
                seq = list(value)
            except TypeError:
                raise TypeError("%s must be a sequence of %d values, got %r" % (what, n, value))
            if len(seq) != n:
                raise _lib.InvalidArgumentError("%s must have %d values, got %d"
                                                % (what, n, len(seq)))
            arr = getattr(obj, name)
            for i, v in enumerate(seq):
                arr[i] = _scalar(v, ctype._type_, "%s[%d]" % (what, i))
        else:
            setattr(obj, name, _scalar(value, ctype, what))
    return struct


def build(struct_name, kwargs, scopes=None, threads=None):
    """The default struct with kwargs applied; threads (when not None) goes to
    every field named threads unless one was given by path."""
    struct = default(struct_name)
    resolved = resolve(struct_name, kwargs, scopes)
    assign(struct, struct_name, resolved)
    if threads is not None:
        t = _scalar(threads, ctypes.c_int, "threads")
        if t < 0:
            raise _lib.InvalidArgumentError("threads must be >= 0 (0: OpenMP's default), got %d" % t)
        every = {path: t for path, *_ in leaves(struct_name)
                 if path[-1] == "threads" and path not in resolved}
        assign(struct, struct_name, every)
    return struct, resolved


def to_dict(struct, struct_name):
    """A struct as a dict: enums by short name, nested structs as dicts,
    arrays as lists, C strings as str; other pointers are left out."""
    out = {}
    for name, kind, ctype, n, _ in FIELDS[struct_name]:
        v = getattr(struct, name)
        if kind == "struct":
            out[name] = to_dict(v, ctype)
        elif kind == "enum":
            out[name] = enum_name(ctype, v)
        elif kind == "pointer":
            if ctype == "char":
                out[name] = v.decode("utf-8", "replace") if v else None
        elif kind == "funcptr":
            continue
        elif n:
            out[name] = v.decode("utf-8", "replace") if isinstance(v, bytes) else list(v)
        else:
            out[name] = v
    return out


def defaults(struct_name):
    """The library's defaults of a params struct as a nested dict."""
    return to_dict(default(struct_name), struct_name)


def _first_clause(doc, width=64):
    doc = " ".join(doc.split())
    if len(doc) <= width:
        return doc
    cut = doc[:width]
    sp = cut.rfind(" ")
    return (cut[:sp] if sp > 20 else cut) + " ..."


def describe(struct_name, prefix=(), indent="    ", skip=()):
    """Help lines: every settable field, its default and its comment."""
    d = default(struct_name)
    lines = []
    for path, kind, ctype, n, doc in leaves(struct_name):
        if path[0] in skip:
            continue
        obj = d
        for p in path:
            obj = getattr(obj, p)
        if kind == "enum":
            val = repr(enum_name(ctype, obj))
        elif n:
            val = repr(tuple(obj))
        elif isinstance(obj, float):
            val = "%g" % obj
        else:
            val = repr(obj)
        name = "__".join(path[len(prefix):] if path[:len(prefix)] == prefix else path)
        lines.append("%s%s=%s  %s" % (indent, name, val, _first_clause(doc)))
    return lines
