#!/usr/bin/env python3
"""Generate C++ reflection for the Poise IDL topic types.

fastddsgen gives one C++ class per IDL struct, but no way to walk its fields. Tools (topic echo
and pub, JSON, the recorder), validation of incoming samples (bad length fields, NaN) and the
interop test all need that walk. This script reads the same IDL files (the subset Poise uses:
modules, constants, enums, @final structs with primitive, string, bounded string, sequence,
array and nested-struct members) and writes one header with:

  - poise::msg::visit_fields(sample, visitor): calls visitor(FieldInfo, member_ref) per member,
    in declaration order, for const and non-const samples;
  - enum name tables (EnumTraits<E>);
  - TopicTypeList: the structs that carry a Header (the topic types), with their IDL names.

Length fields: a member whose comment contains "(<= NAME)" or "(<= 123)" is a count that bounds
the arrays of the same struct whose size equals that bound (see idl/README.md).

Usage: gen_reflection.py --out FILE IDL...
"""

import argparse
import os
import re
import sys

PRIMITIVES = {
    "double": "double",
    "float": "float",
    "boolean": "bool",
    "octet": "uint8_t",
    "char": "char",
    "short": "int16_t",
    "unsigned short": "uint16_t",
    "long": "int32_t",
    "unsigned long": "uint32_t",
    "long long": "int64_t",
    "unsigned long long": "uint64_t",
}


class IdlError(Exception):
    pass


class Member:
    def __init__(self, type_name, name, dims, comment, file, line):
        self.type_name = type_name  # IDL type text
        self.name = name
        self.dims = dims  # list of ints (array dimensions)
        self.comment = comment
        self.file = file
        self.line = line
        self.count_bound = None  # int if this member is a length field
        self.bounded_by = None  # name of the count member bounding this array


class Struct:
    def __init__(self, name, scope):
        self.name = name
        self.scope = scope
        self.members = []

    @property
    def qualified(self):
        return "::".join(self.scope + [self.name])


def strip_block_comments(text):
    return re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)


def parse(files):
    consts = {}
    enums = {}  # name -> (scope, [values])
    structs = []  # in order
    for path in files:
        text = strip_block_comments(open(path, encoding="utf-8").read())
        scope = []
        in_struct = None
        in_enum = None
        last_member = None
        pending_final = False
        for lineno, raw in enumerate(text.splitlines(), 1):
            code, _, comment = raw.partition("//")
            code = code.strip()
            comment = comment.strip()
            where = f"{os.path.basename(path)}:{lineno}"
            if not code:
                if comment and last_member is not None and in_struct is not None:
                    last_member.comment += " " + comment
                continue
            if code.startswith("#"):
                continue
            last_member = None if in_struct is None else last_member
            m = re.match(r"module\s+(\w+)\s*\{$", code)
            if m:
                scope.append(m.group(1))
                continue
            if in_enum is not None:
                body = code.rstrip("};").strip()
                for item in filter(None, (v.strip() for v in body.split(","))):
                    if not re.fullmatch(r"\w+", item):
                        raise IdlError(f"{where}: enumerator '{item}' not understood")
                    in_enum[1].append(item)
                if "}" in code:
                    in_enum = None
                continue
            m = re.match(r"enum\s+(\w+)\s*\{(.*)$", code)
            if m:
                in_enum = (m.group(1), [])
                enums[m.group(1)] = (list(scope), in_enum[1])
                rest = m.group(2).strip()
                if rest:
                    for item in filter(None, (v.strip() for v in rest.rstrip("};").split(","))):
                        in_enum[1].append(item)
                    if "}" in rest:
                        in_enum = None
                continue
            m = re.match(r"const\s+[\w\s]+?\s+(\w+)\s*=\s*(\d+)\s*;$", code)
            if m:
                consts[m.group(1)] = int(m.group(2))
                continue
            m = re.match(r"(@final\s+)?struct\s+(\w+)\s*\{$", code)
            if m:
                if not (m.group(1) or pending_final):
                    raise IdlError(f"{where}: struct {m.group(2)} must be @final (dds-notes.md)")
                in_struct = Struct(m.group(2), list(scope))
                structs.append(in_struct)
                pending_final = False
                continue
            if code == "@final":
                # "@final" alone on a line before "struct X {"
                pending_final = True
                continue
            if code in ("};",):
                if in_struct is not None:
                    in_struct = None
                elif scope:
                    scope.pop()
                continue
            if in_struct is not None:
                m = re.match(r"(.+?)\s+(\w+)\s*((?:\[\s*\w+\s*\])*)\s*;$", code)
                if not m:
                    raise IdlError(f"{where}: member '{code}' not understood")
                type_name = re.sub(r"\s+", " ", m.group(1).strip())
                dims = []
                for d in re.findall(r"\[\s*(\w+)\s*\]", m.group(3)):
                    dims.append(int(d) if d.isdigit() else consts[d])
                member = Member(type_name, m.group(2), dims, comment, where, lineno)
                in_struct.members.append(member)
                last_member = member
                continue
            raise IdlError(f"{where}: '{code}' not understood")
    # length fields
    for s in structs:
        for mem in s.members:
            b = re.search(r"\(<=\s*(\w+)\s*\)", mem.comment)
            if b:
                tok = b.group(1)
                mem.count_bound = int(tok) if tok.isdigit() else consts.get(tok)
                if mem.count_bound is None:
                    raise IdlError(f"{mem.file}: unknown constant {tok} in length marker")
        for mem in s.members:
            if mem.count_bound is None:
                continue
            bounded = [o for o in s.members if o.dims and o.dims[0] == mem.count_bound]
            if not bounded:
                raise IdlError(f"{mem.file}: length field {mem.name} bounds no array")
            for o in bounded:
                o.bounded_by = mem.name
    return consts, enums, structs


def cpp_type(type_name, enums, struct_names):
    if type_name in PRIMITIVES:
        return PRIMITIVES[type_name]
    if type_name == "string" or re.fullmatch(r"string<\s*\d+\s*>", type_name):
        return "std::string"
    m = re.fullmatch(r"sequence<\s*(.+?)\s*(?:,\s*(\d+)\s*)?>", type_name)
    if m:
        return f"std::vector<{cpp_type(m.group(1), enums, struct_names)}>"
    if type_name in enums or type_name in struct_names:
        return type_name
    raise IdlError(f"type '{type_name}' not supported by gen_reflection.py")


def string_bound(type_name):
    m = re.fullmatch(r"string<\s*(\d+)\s*>", type_name)
    return int(m.group(1)) if m else 0


def sequence_bound(type_name):
    m = re.fullmatch(r"sequence<\s*(.+?)\s*,\s*(\d+)\s*>", type_name)
    return int(m.group(2)) if m else 0


def header_name(path):
    return os.path.splitext(os.path.basename(path))[0] + ".h"


def generate(files, out):
    consts, enums, structs = parse(files)
    struct_names = {s.name for s in structs}
    lines = []
    w = lines.append
    w("// Generated by idl/gen_reflection.py from the IDL files. Do not edit.")
    w("#pragma once")
    w("")
    w("#include <array>")
    w("#include <cstddef>")
    w("#include <cstdint>")
    w("#include <string>")
    w("#include <string_view>")
    w("#include <tuple>")
    w("#include <type_traits>")
    w("#include <vector>")
    w("")
    for path in files:
        w(f"#include <poise/msg/{header_name(path)}>")
    w("")
    w("namespace poise::msg {")
    w("")
    w("/// What a visitor learns about one member besides its value.")
    w("struct FieldInfo {")
    w("  std::string_view name;       ///< member name as in the IDL")
    w("  std::string_view idl_type;   ///< IDL type text, e.g. \"double\", \"string<64>\"")
    w("  std::size_t max_length;      ///< bound of a bounded string/sequence; 0 = unbounded")
    w("  std::string_view count_field;  ///< for an array: the member holding its valid length")
    w("  std::uint32_t count_bound;   ///< for a length field: its maximum; 0 otherwise")
    w("};")
    w("")
    w("/// Enumerator names of an IDL enum, in declaration order (value i has name names[i]).")
    w("template <class E>")
    w("struct EnumTraits;")
    w("")
    for name, (scope, values) in enums.items():
        w("template <>")
        w(f"struct EnumTraits<{name}> {{")
        w(f"  static constexpr std::string_view idl_name = \"{'::'.join(scope + [name])}\";")
        w(f"  static constexpr std::array<std::string_view, {len(values)}> names = {{")
        for v in values:
            w(f"      \"{v}\",")
        w("  };")
        w("};")
        w("")
    w("/// True for the IDL structs that visit_fields() knows.")
    w("template <class T>")
    w("struct IsIdlStruct : std::false_type {};")
    for s in structs:
        w(f"template <>")
        w(f"struct IsIdlStruct<{s.name}> : std::true_type {{}};")
    w("")
    w("/// IDL-qualified name of a struct, the DDS type name fastddsgen registers.")
    w("template <class T>")
    w("struct IdlName;")
    for s in structs:
        w(f"template <>")
        w(f"struct IdlName<{s.name}> {{")
        w(f"  static constexpr std::string_view value = \"{s.qualified}\";")
        w("};")
    w("")
    for s in structs:
        w(f"/// Visits the members of {s.qualified} in declaration order.")
        w("template <class S, class V>")
        w(f"  requires std::is_same_v<std::remove_const_t<S>, {s.name}>")
        w(f"void visit_fields(S& s, V&& v) {{")
        for m in s.members:
            cpp_type(m.type_name, enums, struct_names)  # validates the type
            max_len = string_bound(m.type_name) or sequence_bound(m.type_name)
            info = (f"FieldInfo{{\"{m.name}\", \"{m.type_name}\", {max_len}, "
                    f"\"{m.bounded_by or ''}\", {m.count_bound or 0}}}")
            w(f"  v({info}, s.{m.name}());")
        w("}")
        w("")
    topics = [s for s in structs if any(m.name == "header" and m.type_name == "Header"
                                          for m in s.members)]
    w("/// The topic types: every struct whose first member is a Header.")
    w("using TopicTypeList = std::tuple<" + ", ".join(s.name for s in topics) + ">;")
    w("")
    w("}  // namespace poise::msg")
    w("")
    text = "\n".join(lines)
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    old = open(out, encoding="utf-8").read() if os.path.exists(out) else None
    if old != text:
        with open(out, "w", encoding="utf-8") as f:
            f.write(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", required=True, help="header to write")
    ap.add_argument("idl", nargs="+", help="IDL files, in dependency order or any order")
    args = ap.parse_args()
    try:
        generate(args.idl, args.out)
    except (IdlError, OSError, KeyError) as e:
        print(f"gen_reflection.py: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
