#!/usr/bin/env python3
"""Generates the ctypes declarations of the tessel package from include/tessel.h.

The header is regular: typedef'd enums and structs of scalars, fixed arrays,
pointers, function pointers and earlier structs, opaque handles, plain function
prototypes, and #defines of numbers and strings (one X-macro table for the
status codes). This script parses exactly that much C and fails loudly, naming
the line, on anything else, so a new construct in the header stops the build
instead of producing wrong bindings.

Outputs (both written only when their content changes):
  --py FILE   _abi.py: ctypes Structure classes with their _fields_, the
              functions' argtypes/restype, the enums, the constants, and for
              every struct field its C type and its header comment (the
              package builds its keyword parameters and help from these);
  --c FILE    a C program printing sizeof, alignment and every field's offset
              of every struct, every enumerator and every numeric constant as
              the compiler sees them; python/check_abi.py compares that with
              ctypes (a ctest test), so the parse itself is checked.

usage: gen_abi.py HEADER --py OUT.py [--c OUT.c]
Standard library only.
"""
import argparse
import hashlib
import os
import re
import sys

# C scalar types -> (ctypes expression, kind). kind: int, float, char, bool.
SCALARS = {
    "char": ("ctypes.c_char", "char"),
    "signed char": ("ctypes.c_byte", "int"),
    "unsigned char": ("ctypes.c_ubyte", "int"),
    "short": ("ctypes.c_short", "int"),
    "unsigned short": ("ctypes.c_ushort", "int"),
    "int": ("ctypes.c_int", "int"),
    "unsigned": ("ctypes.c_uint", "int"),
    "unsigned int": ("ctypes.c_uint", "int"),
    "long": ("ctypes.c_long", "int"),
    "unsigned long": ("ctypes.c_ulong", "int"),
    "long long": ("ctypes.c_longlong", "int"),
    "unsigned long long": ("ctypes.c_ulonglong", "int"),
    "float": ("ctypes.c_float", "float"),
    "double": ("ctypes.c_double", "float"),
    "size_t": ("ctypes.c_size_t", "int"),
    "int8_t": ("ctypes.c_int8", "int"),
    "uint8_t": ("ctypes.c_uint8", "int"),
    "int16_t": ("ctypes.c_int16", "int"),
    "uint16_t": ("ctypes.c_uint16", "int"),
    "int32_t": ("ctypes.c_int32", "int"),
    "uint32_t": ("ctypes.c_uint32", "int"),
    "int64_t": ("ctypes.c_int64", "int"),
    "uint64_t": ("ctypes.c_uint64", "int"),
    "bool": ("ctypes.c_bool", "bool"),
    "_Bool": ("ctypes.c_bool", "bool"),
}
# Constants the header may use from <stdint.h>.
STDINT = {
    "UINT8_MAX": 0xFF, "UINT16_MAX": 0xFFFF, "UINT32_MAX": 0xFFFFFFFF,
    "UINT64_MAX": 0xFFFFFFFFFFFFFFFF, "INT32_MAX": 0x7FFFFFFF, "SIZE_MAX": None,
}


class HeaderError(Exception):
    pass


TOKEN_RE = re.compile(r"""
    (?P<comment>/\*.*?\*/|//[^\n]*)
  | (?P<string>"(?:\\.|[^"\\])*")
  | (?P<number>0[xX][0-9a-fA-F]+[uUlL]*|\d+(?:\.\d*)?(?:[eE][-+]?\d+)?[uUlLfF]*)
  | (?P<ident>[A-Za-z_]\w*)
  | (?P<punct>\.\.\.|[{}()\[\];,*=<>+\-|&~])
  | (?P<space>\s+)
""", re.S | re.X)


class Tok:
    __slots__ = ("kind", "text", "line", "end_line")

    def __init__(self, kind, text, line, end_line):
        self.kind, self.text, self.line, self.end_line = kind, text, line, end_line

    def __repr__(self):
        return "%s:%r@%d" % (self.kind, self.text, self.line)


def preprocess(text, path):
    """Returns (code lines with preprocessor lines blanked, defines, x-lists).

    Line numbers are kept (blanked lines stay as empty lines). #ifdef
    __cplusplus blocks are dropped; other conditionals only guard #defines,
    which are collected from every branch (TESSEL_API is the only one defined
    in several branches and is removed from the code anyway)."""
    lines = text.split("\n")
    out = []
    defines = {}
    xlists = {}
    skipping = []  # stack of bools: inside an #ifdef __cplusplus block
    i = 0
    while i < len(lines):
        line = lines[i]
        start = i
        if line.lstrip().startswith("#"):
            logical = line
            while logical.endswith("\\"):
                i += 1
                logical = logical[:-1] + " " + lines[i]
            directive = logical.strip()[1:].strip()
            word = directive.split(None, 1)[0] if directive else ""
            rest = directive[len(word):].strip()
            if word in ("if", "ifdef", "ifndef"):
                skipping.append(word == "ifdef" and rest == "__cplusplus")
            elif word == "endif":
                if not skipping:
                    raise HeaderError("%s:%d: #endif without #if" % (path, start + 1))
                skipping.pop()
            elif word in ("else", "elif"):
                if skipping and skipping[-1]:
                    skipping[-1] = False
            elif word == "define" and not any(skipping):
                m = re.match(r"(\w+)\(X\)\s*(.*)$", rest)
                if m:
                    items = re.findall(r'X\(\s*(\w+)\s*,\s*("(?:\\.|[^"\\])*")\s*\)', m.group(2))
                    if not items:
                        raise HeaderError("%s:%d: X-macro %s has no X(NAME, \"text\") item"
                                          % (path, start + 1, m.group(1)))
                    xlists[m.group(1)] = [(n, s[1:-1]) for n, s in items]
                else:
                    m = re.match(r"(\w+)(\s+(.*))?$", rest)
                    if m and "(" not in m.group(1):
                        defines[m.group(1)] = (m.group(3) or "").strip()
            for _ in range(start, i + 1):
                out.append("")
        else:
            out.append("" if any(skipping) else line)
        i += 1
    if skipping:
        raise HeaderError("%s: unterminated #if" % path)
    return "\n".join(out), defines, xlists


def tokenize(code, path):
    toks = []
    pos = 0
    line = 1
    while pos < len(code):
        m = TOKEN_RE.match(code, pos)
        if not m:
            raise HeaderError("%s:%d: cannot read %r" % (path, line, code[pos:pos + 20]))
        kind = m.lastgroup
        text = m.group(kind)
        nl = text.count("\n")
        if kind != "space":
            toks.append(Tok(kind, text, line, line + nl))
        line += nl
        pos = m.end()
    return toks


def eval_number(text, consts, path, line):
    text = text.strip()
    if text.startswith("(") and text.endswith(")"):
        text = text[1:-1].strip()
    if text in consts:
        return consts[text]
    if text in STDINT and STDINT[text] is not None:
        return STDINT[text]
    m = re.fullmatch(r"-?(0[xX][0-9a-fA-F]+|\d+)[uUlL]*", text)
    if m:
        return int(text.rstrip("uUlL"), 0)
    m = re.fullmatch(r"-?\d+\.\d*(?:[eE][-+]?\d+)?|-?\d+[eE][-+]?\d+", text)
    if m:
        return float(text)
    raise HeaderError("%s:%d: not a number the generator understands: %r" % (path, line, text))


def comment_text(tok):
    t = tok.text
    if t.startswith("//"):
        return t[2:].strip()
    body = t[2:-2]
    parts = [re.sub(r"^\s*\*?\s?", "", l).rstrip() for l in body.split("\n")]
    return " ".join(p.strip() for p in parts if p.strip())


class Parser:
    def __init__(self, toks, path, xlists):
        self.toks = toks
        self.path = path
        self.xlists = xlists
        self.enums = {}       # name -> [(enumerator, value, comment)]
        self.structs = {}     # name -> [field dicts]; None for opaque
        self.order = []       # struct names in definition order
        self.functions = []   # (name, ret type dict, [arg type dicts], line)
        self.typedef_kind = {}  # name -> "enum" | "struct" | "opaque"

    def fail(self, tok, msg):
        raise HeaderError("%s:%d: %s" % (self.path, tok.line if tok else 0, msg))

    def run(self):
        decl = []
        depth = 0
        for t in self.toks:
            if t.kind == "comment" and depth == 0:
                continue
            decl.append(t)
            if t.text == "{":
                depth += 1
            elif t.text == "}":
                depth -= 1
            elif t.text == ";" and depth == 0:
                self.declaration(decl)
                decl = []
        if [t for t in decl if t.kind != "comment"]:
            self.fail(decl[0], "declaration without ';'")

    def declaration(self, toks):
        toks = [t for t in toks if t.text != "TESSEL_API"]
        code = [t for t in toks if t.kind != "comment"]
        if code[0].text == "typedef":
            if code[1].text == "enum":
                self.enum(toks)
            elif code[1].text == "struct":
                if code[3].text == "{":
                    self.struct(toks)
                elif len(code) == 5 and code[4].text == ";":
                    self.typedef_kind[code[3].text] = "opaque"
                    self.structs[code[3].text] = None
                else:
                    self.fail(code[0], "unsupported struct typedef")
            else:
                self.fail(code[0], "unsupported typedef (only enums and structs)")
        else:
            self.function(code)

    def enum(self, toks):
        code = [t for t in toks if t.kind != "comment"]
        tag = code[2].text
        if code[3].text != "{" or code[-3].text != "}" or code[-2].text != tag:
            self.fail(code[0], "enum %s: expected 'typedef enum T { ... } T;'" % tag)
        body = []
        start = toks.index(code[3]) + 1
        end = len(toks) - 1 - toks[::-1].index(code[-3])
        body = toks[start:end]
        items = []
        value = -1
        i = 0
        consts = {n: v for n, v, _ in items}
        while i < len(body):
            t = body[i]
            if t.kind == "comment":
                # A comment on the line of the previous enumerator is its doc.
                if items and t.line == items[-1][3]:
                    n, v, c, l = items[-1]
                    items[-1] = (n, v, (c + " " + comment_text(t)).strip(), l)
                i += 1
                continue
            if t.kind != "ident":
                self.fail(t, "enum %s: unexpected %r" % (tag, t.text))
            if t.text in self.xlists and i + 3 < len(body) and body[i + 1].text == "(":
                j = i
                while body[j].text != ")":
                    j += 1
                for name, _ in self.xlists[t.text]:
                    value += 1
                    items.append((name, value, "", t.line))
                i = j + 1
                continue
            name = t.text
            i += 1
            if i < len(body) and body[i].text == "=":
                expr = []
                i += 1
                while i < len(body) and body[i].text != "," and body[i].kind != "comment":
                    expr.append(body[i].text)
                    i += 1
                consts = {n: v for n, v, _, _ in items}
                value = eval_number("".join(expr), consts, self.path, t.line)
            else:
                value += 1
            items.append((name, value, "", t.line))
            if i < len(body) and body[i].text == ",":
                i += 1
        self.enums[tag] = [(n, v, c) for n, v, c, _ in items]
        self.typedef_kind[tag] = "enum"

    def parse_type(self, words, tok):
        """words: type tokens without 'const'. Returns a type dict."""
        name = " ".join(words)
        if name in SCALARS:
            return {"kind": "scalar", "c": name}
        if name in self.typedef_kind:
            k = self.typedef_kind[name]
            return {"kind": k, "c": name}
        if name == "void":
            return {"kind": "void", "c": "void"}
        self.fail(tok, "unknown type %r" % name)

    def declarator(self, toks, ctx):
        """Parses 'const T *name[N]' or a function pointer; returns field dict."""
        code = [t for t in toks if t.kind != "comment"]
        if not code:
            self.fail(toks[0] if toks else None, "%s: empty declaration" % ctx)
        # Function pointer: RET ( * name ) ( args )
        if "(" in [t.text for t in code]:
            p = [t.text for t in code].index("(")
            if code[p + 1].text != "*" or code[p + 3].text != ")" or code[p + 4].text != "(":
                self.fail(code[0], "%s: unsupported declarator" % ctx)
            ret = self.simple_type(code[:p], ctx)
            args = self.arg_list(code[p + 5:-1], ctx)
            return {"name": code[p + 2].text, "kind": "funcptr", "ret": ret, "args": args}
        # The last identifier before any '[' is the name.
        brk = [i for i, t in enumerate(code) if t.text == "["]
        head = code[:brk[0]] if brk else code
        name_tok = head[-1]
        if name_tok.kind != "ident":
            self.fail(name_tok, "%s: expected a name" % ctx)
        typ = self.simple_type(head[:-1], ctx)
        if brk:
            dims = []
            i = brk[0]
            while i < len(code) and code[i].text == "[":
                j = i + 1
                expr = []
                while code[j].text != "]":
                    expr.append(code[j].text)
                    j += 1
                dims.append(expr)
                i = j + 1
            if len(dims) != 1:
                self.fail(name_tok, "%s: multi-dimensional arrays are not supported" % ctx)
            typ = dict(typ, array=dims[0])
        return dict(typ, name=name_tok.text)

    def simple_type(self, code, ctx):
        words = []
        ptr = 0
        const = False
        for t in code:
            if t.text == "const":
                const = True
            elif t.text == "*":
                ptr += 1
            elif t.text in ("struct", "enum"):
                continue
            elif t.kind == "ident":
                if ptr:
                    self.fail(t, "%s: unsupported type (qualifier after '*')" % ctx)
                words.append(t.text)
            else:
                self.fail(t, "%s: unexpected %r in a type" % (ctx, t.text))
        if not words:
            self.fail(code[0] if code else None, "%s: missing type" % ctx)
        typ = self.parse_type(words, code[0])
        typ = dict(typ)
        typ["ptr"] = ptr
        typ["const"] = const
        if typ["kind"] == "void" and not ptr:
            typ["kind"] = "void"
        return typ

    def arg_list(self, code, ctx):
        if len(code) == 1 and code[0].text == "void":
            return []
        args = []
        cur = []
        depth = 0
        for t in code + [Tok("punct", ",", code[-1].line if code else 0, 0)]:
            if t.text == "(":
                depth += 1
            elif t.text == ")":
                depth -= 1
            if t.text == "," and depth == 0:
                if cur:
                    if "(" in [c.text for c in cur]:
                        args.append(self.declarator(cur, ctx))
                    else:
                        idents = [c for c in cur if c.kind == "ident" and c.text != "const"]
                        brk = [c for c in cur if c.text == "["]
                        if brk:
                            # An array parameter is a pointer.
                            k = cur.index(brk[0])
                            a = self.simple_type(cur[:k - 1], ctx)
                            a["ptr"] += 1
                            a["name"] = cur[k - 1].text
                        elif len(idents) >= 2 and self.is_type_end(idents):
                            a = self.simple_type(cur[:-1], ctx)
                            a["name"] = cur[-1].text
                        else:
                            a = self.simple_type(cur, ctx)
                            a["name"] = ""
                        args.append(a)
                cur = []
            else:
                cur.append(t)
        return args

    def is_type_end(self, idents):
        # 'unsigned int' is a type, 'size_t count' is type + name.
        return " ".join(i.text for i in idents) not in SCALARS

    def struct(self, toks):
        code = [t for t in toks if t.kind != "comment"]
        tag = code[2].text
        if code[-2].text != tag or code[-3].text != "}":
            self.fail(code[0], "struct %s: expected 'typedef struct T { ... } T;'" % tag)
        start = toks.index(code[3]) + 1
        end = len(toks) - 1 - toks[::-1].index(code[-3])
        body = toks[start:end]
        fields = []
        member = []
        pending_doc = []   # comments on their own lines: for the next member
        last = None        # the members of the previous declaration
        for t in body:
            if t.kind == "comment":
                if last is not None and t.line == last_line and not member:
                    for f in last:
                        f["doc"] = (f["doc"] + " " + comment_text(t)).strip()
                else:
                    pending_doc.append(comment_text(t))
                continue
            member.append(t)
            if t.text == ";":
                decls = self.member(member[:-1], tag)
                doc = " ".join(pending_doc)
                for d in decls:
                    d["doc"] = doc
                fields.extend(decls)
                last = decls
                last_line = t.line
                member = []
                pending_doc = []
        if member:
            self.fail(member[0], "struct %s: member without ';'" % tag)
        if not fields:
            self.fail(code[0], "struct %s has no members" % tag)
        self.structs[tag] = fields
        self.order.append(tag)
        self.typedef_kind[tag] = "struct"

    def member(self, code, tag):
        """'T a, b[3], *c' -> one field dict per declarator."""
        texts = [t.text for t in code]
        if "(" in texts:
            return [self.declarator(code, "struct %s" % tag)]
        # Split at top-level commas: the first part carries the type.
        parts = []
        cur = []
        for t in code:
            if t.text == ",":
                parts.append(cur)
                cur = []
            else:
                cur.append(t)
        parts.append(cur)
        first = self.declarator(parts[0], "struct %s" % tag)
        out = [first]
        if len(parts) > 1:
            # The base type: tokens of the first part before its name/pointers.
            base = []
            for t in parts[0]:
                if t.text in ("*", "[") or t.text == first["name"]:
                    break
                base.append(t)
            for p in parts[1:]:
                out.append(self.declarator(base + p, "struct %s" % tag))
        return out

    def function(self, code):
        texts = [t.text for t in code]
        if "(" not in texts or texts[-2] != ")":
            self.fail(code[0], "unsupported declaration (expected a function prototype)")
        p = texts.index("(")
        name = code[p - 1]
        if name.kind != "ident":
            self.fail(name, "expected a function name")
        ret = self.simple_type(code[:p - 1], "function %s" % name.text)
        args = self.arg_list(code[p + 1:-2], "function %s" % name.text)
        self.functions.append((name.text, ret, args, name.line))


def ctype_expr(t, structs_known=True):
    """ctypes expression for a type dict (field, argument or return)."""
    kind = t["kind"]
    ptr = t.get("ptr", 0)
    if kind == "funcptr":
        ret = "None" if t["ret"]["kind"] == "void" and not t["ret"]["ptr"] else ctype_expr(t["ret"])
        args = ", ".join(ctype_expr(a) for a in t["args"])
        return "ctypes.CFUNCTYPE(%s%s)" % (ret, (", " + args) if args else "")
    if kind == "void":
        base = None
    elif kind == "scalar":
        base = SCALARS[t["c"]][0]
    elif kind == "enum":
        base = "ctypes.c_int"
    elif kind == "opaque":
        base = None
    else:
        base = t["c"]
    if ptr:
        if base is None:
            expr = "ctypes.c_void_p"
            ptr -= 1
        elif base == "ctypes.c_char" and ptr == 1:
            return "ctypes.c_char_p"
        else:
            expr = base
            expr = "ctypes.POINTER(%s)" % expr
            ptr -= 1
        for _ in range(ptr):
            expr = "ctypes.POINTER(%s)" % expr
        return expr
    if base is None:
        raise HeaderError("void or opaque value type for %r" % t.get("name"))
    return base


def field_meta(f):
    kind = f["kind"]
    if kind == "funcptr":
        return (f["name"], "funcptr", None, None)
    if f.get("ptr"):
        return (f["name"], "pointer", f["c"], None)
    return (f["name"], kind, f["c"], f.get("array_len"))


def generate(path):
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    sha = hashlib.sha256(text.encode()).hexdigest()
    code, defines, xlists = preprocess(text, path)
    toks = tokenize(code, path)
    parser = Parser(toks, path, xlists)
    parser.run()

    consts = {}
    strings = {}
    for name, value in defines.items():
        if name in ("TESSEL_H",) or name.startswith("TESSEL_API"):
            continue
        if value.startswith('"'):
            strings[name] = value[1:-1]
            continue
        if value in STDINT and STDINT[value] is not None:
            consts[name] = STDINT[value]
            continue
        try:
            consts[name] = eval_number(value, consts, path, 0)
        except HeaderError:
            continue  # not a plain constant (attribute macros and such)

    enum_values = {}
    for items in parser.enums.values():
        for n, v, _ in items:
            enum_values[n] = v
    # Array lengths.
    for tag in parser.order:
        for f in parser.structs[tag]:
            if "array" in f:
                f["array_len"] = eval_number("".join(f["array"]), dict(consts, **enum_values),
                                             path, 0)
    return parser, consts, strings, xlists, sha


def field_ctype(f):
    expr = ctype_expr(f)
    if "array_len" in f:
        expr = "(%s * %d)" % (expr, f["array_len"])
    return expr


def write_py(parser, consts, strings, xlists, sha, header_name):
    out = []
    w = out.append
    w("# Generated from %s by python/gen_abi.py; do not edit." % header_name)
    w('"""ctypes declarations of the whole tessel.h (generated)."""')
    w("import ctypes")
    w("")
    w("HEADER_SHA256 = %r" % sha)
    w("CONSTANTS = {")
    for k in sorted(consts):
        w("    %r: %r," % (k, consts[k]))
    w("}")
    w("STRINGS = {")
    for k in sorted(strings):
        w("    %r: %r," % (k, strings[k]))
    w("}")
    w("# X-macro tables: NAME -> [(enumerator, text)].")
    w("XLISTS = {")
    for k, items in xlists.items():
        w("    %r: %r," % (k, items))
    w("}")
    w("# enum type -> [(enumerator, value, comment)], in declaration order.")
    w("ENUMS = {")
    for k, items in parser.enums.items():
        w("    %r: [" % k)
        for n, v, c in items:
            w("        (%r, %d, %r)," % (n, v, c))
        w("    ],")
    w("}")
    w("OPAQUE = %r" % sorted(k for k, v in parser.structs.items() if v is None))
    w("")
    for tag in parser.order:
        w("class %s(ctypes.Structure):" % tag)
        w("    pass")
        w("")
    w("")
    for tag in parser.order:
        w("%s._fields_ = [" % tag)
        for f in parser.structs[tag]:
            w("    (%r, %s)," % (f["name"], field_ctype(f)))
        w("]")
    w("")
    w("STRUCTS = {%s}" % ", ".join("%r: %s" % (t, t) for t in parser.order))
    w("# struct -> [(field, kind, C type, array length, comment)]; kind is scalar,")
    w("# enum, struct, pointer or funcptr.")
    w("FIELDS = {")
    for tag in parser.order:
        w("    %r: [" % tag)
        for f in parser.structs[tag]:
            name, kind, c, n = field_meta(f)
            w("        (%r, %r, %r, %r, %r)," % (name, kind, c, n, f.get("doc", "")))
        w("    ],")
    w("}")
    w("# function -> (restype, argtypes)")
    w("FUNCTIONS = {")
    for name, ret, args, _ in parser.functions:
        r = "None" if ret["kind"] == "void" and not ret["ptr"] else ctype_expr(ret)
        w("    %r: (%s, [%s])," % (name, r, ", ".join(ctype_expr(a) for a in args)))
    w("}")
    w("")
    return "\n".join(out)


def write_c(parser, consts, header_name):
    out = []
    w = out.append
    w("/* Generated from %s by python/gen_abi.py: the layout the compiler gives" % header_name)
    w(" * every struct, enumerator and constant, one per line, for check_abi.py. */")
    w("#include <stddef.h>")
    w("#include <stdio.h>")
    w("#include <tessel.h>")
    w("")
    w("int main(void)")
    w("{")
    for tag in parser.order:
        w('    printf("struct %s %%zu %%zu\\n", sizeof(%s), _Alignof(%s));' % (tag, tag, tag))
        for f in parser.structs[tag]:
            w('    printf("field %s.%s %%zu %%zu\\n", offsetof(%s, %s), sizeof(((%s *)0)->%s));'
              % (tag, f["name"], tag, f["name"], tag, f["name"]))
    for items in parser.enums.values():
        for n, _, _ in items:
            w('    printf("enum %s %%lld\\n", (long long)%s);' % (n, n))
    for k in sorted(consts):
        w('    printf("const %s %%llu\\n", (unsigned long long)(%s));' % (k, k))
    w("    return 0;")
    w("}")
    w("")
    return "\n".join(out)


def write_if_changed(path, text):
    try:
        with open(path, encoding="utf-8") as fh:
            if fh.read() == text:
                return
    except OSError:
        pass
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
    os.replace(tmp, path)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("header")
    ap.add_argument("--py", required=True)
    ap.add_argument("--c")
    args = ap.parse_args(argv)
    try:
        parser, consts, strings, xlists, sha = generate(args.header)
    except HeaderError as e:
        sys.stderr.write("gen_abi.py: %s\n" % e)
        return 1
    name = os.path.basename(args.header)
    write_if_changed(args.py, write_py(parser, consts, strings, xlists, sha, name))
    if args.c:
        write_c_text = write_c(parser, consts, name)
        write_if_changed(args.c, write_c_text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
