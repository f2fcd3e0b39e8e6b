#!/usr/bin/env python3
"""Check JSON documents against the protocol's schemas (standard library only).

    python3 validate.py SCHEMA FILE.json|-        one JSON document
    python3 validate.py --lines SCHEMA FILE|-     one JSON document a line

Exit status: 0 when every document is valid, 1 when one is not (each error
printed as "FILE:LINE: error: /json/pointer: message"), 2 for a bad schema,
a file that cannot be read or text that is not JSON ("FILE:LINE:COL: error:
message").

As a module:

    import validate
    schema = validate.load_schema("request.schema.json")
    errors = schema.errors(validate.loads('{"op":"list","id":1}'))   # [] when valid

This is the subset of JSON Schema (draft 2020-12) that the schemas here use,
and nothing more: a keyword it does not know is an error when the schema is
loaded, so that no constraint is ever skipped without a word. Known keywords:
type (null, boolean, integer, number, string, array, object), enum, const,
properties, required, additionalProperties, propertyNames, minProperties,
maxProperties, dependentRequired, items, minItems, maxItems, minimum,
maximum, minLength, maxLength, pattern (a regular expression of Python's re,
searched, as JSON Schema says), oneOf, anyOf, $ref (to "#/$defs/NAME"),
$defs, and the annotations $schema, $comment, title and description.

Numbers are compared exactly: the parser reads them as int or Decimal, so
9007199254740993 is not taken for 2^53 and 1.0 is an integer (as the
draft says). Strings are measured in characters (code points). Text that
JSON does not allow (NaN, Infinity) and objects with a repeated member name
are refused, since which value a reader would keep is anyone's guess.
"""

import decimal
import json
import os
import re
import sys

__all__ = ["Schema", "SchemaError", "load_schema", "loads", "validate"]

ANNOTATIONS = {"$schema", "$comment", "title", "description"}
KEYWORDS = ANNOTATIONS | {
    "$defs", "$ref", "type", "enum", "const", "properties", "required", "additionalProperties",
    "propertyNames", "minProperties", "maxProperties", "dependentRequired", "items", "minItems",
    "maxItems", "minimum", "maximum", "minLength", "maxLength", "pattern", "oneOf", "anyOf",
}
TYPES = {"null", "boolean", "integer", "number", "string", "array", "object"}


class SchemaError(Exception):
    """The schema itself is wrong, or uses what this validator does not support."""


# ---------------------------------------------------------------------------
# JSON text
# ---------------------------------------------------------------------------


def _pairs(pairs):
    out = {}
    for k, v in pairs:
        if k in out:
            raise ValueError("the member %r appears twice in one object" % k)
        out[k] = v
    return out


def _constant(name):
    raise ValueError("%s is not JSON" % name)


def loads(text):
    """Parse JSON text strictly: numbers as int or Decimal (exact), no NaN or
    Infinity, no repeated member names. Raises ValueError (json.JSONDecodeError
    carries the line and column)."""
    return json.loads(text, parse_float=decimal.Decimal, parse_constant=_constant,
                      object_pairs_hook=_pairs)


# ---------------------------------------------------------------------------
# Values
# ---------------------------------------------------------------------------


def _is_number(v):
    return isinstance(v, (int, float, decimal.Decimal)) and not isinstance(v, bool)


def _is_integer(v):
    if isinstance(v, bool):
        return False
    if isinstance(v, int):
        return True
    if isinstance(v, float):
        return v.is_integer()
    if isinstance(v, decimal.Decimal):
        return v.is_finite() and v == v.to_integral_value()
    return False


def _type_of(v):
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "boolean"
    if _is_number(v):
        return "integer" if _is_integer(v) else "number"
    if isinstance(v, str):
        return "string"
    if isinstance(v, list):
        return "array"
    if isinstance(v, dict):
        return "object"
    return type(v).__name__


def _has_type(v, t):
    if t == "number":
        return _is_number(v)
    if t == "integer":
        return _is_integer(v)
    return _type_of(v) == t


def _equal(a, b):
    """JSON equality: numbers by value, booleans apart from numbers."""
    if _is_number(a) and _is_number(b):
        return a == b
    if isinstance(a, bool) or isinstance(b, bool):
        return isinstance(a, bool) and isinstance(b, bool) and a == b
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


def _show(v, limit=60):
    if isinstance(v, decimal.Decimal):
        text = str(v)
    else:
        try:
            text = json.dumps(v, ensure_ascii=False, default=str)
        except (TypeError, ValueError):
            text = repr(v)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _pointer(path):
    if not path:
        return "/"
    return "".join("/" + str(p).replace("~", "~0").replace("/", "~1") for p in path)


# ---------------------------------------------------------------------------
# Schemas
# ---------------------------------------------------------------------------


class Schema:
    """A schema, checked for keywords this validator does not know."""

    def __init__(self, root, name="schema"):
        self.root = root
        self.name = name
        self._check(root, "#")

    # -- checking the schema --

    def _fail(self, where, message):
        raise SchemaError("%s: %s: %s" % (self.name, where, message))

    def _check(self, s, where):
        if isinstance(s, bool):
            return
        if not isinstance(s, dict):
            self._fail(where, "a schema is an object or a boolean, not %s" % _type_of(s))
        for k, v in s.items():
            at = where + "/" + k
            if k not in KEYWORDS:
                self._fail(at, "the keyword '%s' is not supported by this validator" % k)
            if k in ("title", "description", "$comment", "$schema"):
                if not isinstance(v, str):
                    self._fail(at, "must be a string")
            elif k == "$ref":
                self._resolve(v, at)
            elif k in ("$defs", "properties", "dependentRequired"):
                if not isinstance(v, dict):
                    self._fail(at, "must be an object")
                for name, sub in v.items():
                    if k == "dependentRequired":
                        self._names(sub, at + "/" + name)
                    else:
                        self._check(sub, at + "/" + name)
            elif k == "type":
                ts = v if isinstance(v, list) else [v]
                if not ts or any(t not in TYPES for t in ts):
                    self._fail(at, "must be one of %s or a list of them" % ", ".join(sorted(TYPES)))
            elif k == "enum":
                if not isinstance(v, list) or not v:
                    self._fail(at, "must be a non-empty array")
            elif k == "required":
                self._names(v, at)
            elif k in ("additionalProperties", "propertyNames", "items"):
                self._check(v, at)
            elif k in ("oneOf", "anyOf"):
                if not isinstance(v, list) or not v:
                    self._fail(at, "must be a non-empty array of schemas")
                for i, sub in enumerate(v):
                    self._check(sub, "%s/%d" % (at, i))
            elif k in ("minimum", "maximum"):
                if not _is_number(v):
                    self._fail(at, "must be a number")
            elif k == "pattern":
                try:
                    re.compile(v)
                except (TypeError, re.error):
                    self._fail(at, "must be a regular expression")
            elif k in ("minProperties", "maxProperties", "minItems", "maxItems", "minLength",
                       "maxLength"):
                if not _is_integer(v) or v < 0:
                    self._fail(at, "must be a whole number, not negative")

    def _names(self, v, at):
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            self._fail(at, "must be an array of strings")

    def _resolve(self, ref, where):
        prefix = "#/$defs/"
        if not isinstance(ref, str) or not ref.startswith(prefix):
            self._fail(where, "only references to '#/$defs/NAME' are supported, not %r" % (ref,))
        name = ref[len(prefix):]
        defs = self.root.get("$defs") if isinstance(self.root, dict) else None
        if not isinstance(defs, dict) or name not in defs:
            self._fail(where, "%s names no definition" % ref)
        return defs[name]

    # -- validating --

    def errors(self, instance):
        """The reasons @instance does not match, as "/pointer: message" lines ([] if it does)."""
        return ["%s: %s" % (_pointer(p), m) for p, m, _ in self._errors(self.root, instance, [])]

    def is_valid(self, instance):
        return not self._errors(self.root, instance, [])

    def _errors(self, s, v, path):
        """A list of (path, message, kind) where kind names the failed keyword."""
        if s is True:
            return []
        if s is False:
            return [(path, "nothing is allowed here", "false")]
        out = []

        def err(message, kind, at=None):
            out.append((path if at is None else at, message, kind))

        if "$ref" in s:
            out += self._errors(self._resolve(s["$ref"], "$ref"), v, path)
        if "type" in s:
            ts = s["type"] if isinstance(s["type"], list) else [s["type"]]
            if not any(_has_type(v, t) for t in ts):
                # Whatever else the schema says is about values of its type.
                err("%s is %s, not %s" % (_show(v), _article(_type_of(v)),
                                          " or ".join(_article(t) for t in ts)), "type")
                return out
        if "const" in s and not _equal(v, s["const"]):
            err("%s is not %s" % (_show(v), _show(s["const"])), "const")
        if "enum" in s and not any(_equal(v, e) for e in s["enum"]):
            err("%s is not one of %s" % (_show(v), ", ".join(_show(e) for e in s["enum"])), "enum")
        if _is_number(v):
            if "minimum" in s and v < s["minimum"]:
                err("%s is below the minimum %s" % (_show(v), _show(s["minimum"])), "minimum")
            if "maximum" in s and v > s["maximum"]:
                err("%s is above the maximum %s" % (_show(v), _show(s["maximum"])), "maximum")
        if isinstance(v, str):
            if "minLength" in s and len(v) < s["minLength"]:
                err("%s is shorter than %d characters" % (_show(v), s["minLength"]), "minLength")
            if "maxLength" in s and len(v) > s["maxLength"]:
                err("a string of %d characters, longer than %d" % (len(v), s["maxLength"]),
                    "maxLength")
            if "pattern" in s and not re.search(s["pattern"], v):
                err("%s does not match %s" % (_show(v), s["pattern"]), "pattern")
        if isinstance(v, list):
            if "minItems" in s and len(v) < s["minItems"]:
                err("%d items, fewer than %d" % (len(v), s["minItems"]), "minItems")
            if "maxItems" in s and len(v) > s["maxItems"]:
                err("%d items, more than %d" % (len(v), s["maxItems"]), "maxItems")
            if "items" in s:
                for i, x in enumerate(v):
                    out += self._errors(s["items"], x, path + [i])
        if isinstance(v, dict):
            out += self._object_errors(s, v, path, err)
        for k in ("oneOf", "anyOf"):
            if k in s:
                out += self._alternatives(k, s[k], v, path)
        return out

    def _object_errors(self, s, v, path, err):
        out = []
        props = s.get("properties", {})
        for name in s.get("required", []):
            if name not in v:
                err("'%s' is required" % name, "required")
        for name, deps in s.get("dependentRequired", {}).items():
            if name in v:
                for d in deps:
                    if d not in v:
                        err("'%s' is required with '%s'" % (d, name), "dependentRequired")
        if "minProperties" in s and len(v) < s["minProperties"]:
            err("%d members, fewer than %d" % (len(v), s["minProperties"]), "minProperties")
        if "maxProperties" in s and len(v) > s["maxProperties"]:
            err("%d members, more than %d" % (len(v), s["maxProperties"]), "maxProperties")
        for name, x in v.items():
            if "propertyNames" in s:
                for p, m, kind in self._errors(s["propertyNames"], name, path + [name]):
                    out.append((p, "member name: " + m, kind))
            if name in props:
                out += self._errors(props[name], x, path + [name])
            elif "additionalProperties" in s:
                if s["additionalProperties"] is False:
                    err("'%s' is not a member this message has" % name, "additionalProperties",
                        path + [name])
                else:
                    out += self._errors(s["additionalProperties"], x, path + [name])
        return out

    def _alternatives(self, k, alts, v, path):
        results = [self._errors(a, v, path) for a in alts]
        good = sum(1 for r in results if not r)
        if k == "oneOf" and good > 1:
            return [(path, "matches %d of the alternatives; exactly one must match" % good, k)]
        if good:
            return []
        # Report the alternative that came nearest. One told apart by a member
        # (such as "op") that the instance does not have is not about it at
        # all; one whose type the instance does not have is far too.
        tags = [_tag(self, a) for a in alts]
        near = [i for i, t in enumerate(tags)
                if t is None or (isinstance(v, dict) and _equal(v.get(t[0]), t[1]))]
        if not near:
            if all(t and t[0] == tags[0][0] for t in tags) and isinstance(v, dict):
                member = tags[0][0]
                names = ", ".join(_show(t[1]) for t in tags)
                if member not in v:
                    return [(path, "'%s' is required: one of %s" % (member, names), "required")]
                return [(path + [member], "%s is not one of %s" % (_show(v[member]), names),
                         "const")]
            near = range(len(alts))

        def distance(i):
            wrong_type = any(kind == "type" and len(p) == len(path) for p, _, kind in results[i])
            return (wrong_type, len(results[i]))

        return results[min(near, key=distance)]


def _tag(schema, alt):
    """(member, value) when the alternative @alt is told apart by a const member
    (such as "op"), else None."""
    s = alt
    while isinstance(s, dict) and "$ref" in s:
        s = schema._resolve(s["$ref"], "$ref")
    if not isinstance(s, dict):
        return None
    for name, p in s.get("properties", {}).items():
        if isinstance(p, dict) and "const" in p and name in s.get("required", []):
            return name, p["const"]
    return None


def _article(t):
    return ("an " if t[0] in "aeiou" else "a ") + t


def load_schema(path):
    """The schema in the file @path, checked (SchemaError, OSError, ValueError)."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    try:
        root = loads(text)
    except json.JSONDecodeError as e:
        raise SchemaError("%s:%d:%d: %s" % (path, e.lineno, e.colno, e.msg))
    except ValueError as e:
        raise SchemaError("%s: %s" % (path, e))
    return Schema(root, os.path.basename(path))


def validate(schema, instance):
    """The errors of @instance against @schema (a Schema, or a schema as Python data)."""
    if not isinstance(schema, Schema):
        schema = Schema(schema)
    return schema.errors(instance)


# ---------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------


def _documents(name, text, lines):
    """(line number, document or None, parse error or None) of @text."""
    if not lines:
        try:
            yield 1, loads(text), None
        except json.JSONDecodeError as e:
            yield e.lineno, None, "%d: %s" % (e.colno, e.msg)
        except ValueError as e:
            yield 1, None, str(e)
        return
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            yield n, loads(line), None
        except json.JSONDecodeError as e:
            yield n, None, "%d: %s" % (e.colno, e.msg)
        except ValueError as e:
            yield n, None, str(e)


def main(argv):
    args = list(argv[1:])
    lines = "--lines" in args
    if lines:
        args.remove("--lines")
    if len(args) != 2:
        print("usage: validate.py [--lines] SCHEMA FILE.json|-", file=sys.stderr)
        return 2
    try:
        schema = load_schema(args[0])
    except (OSError, SchemaError) as e:
        print("validate.py: %s" % e, file=sys.stderr)
        return 2
    name = "<stdin>" if args[1] == "-" else args[1]
    try:
        if args[1] == "-":
            text = sys.stdin.read()
        else:
            with open(args[1], encoding="utf-8") as f:
                text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        print("validate.py: %s: %s" % (name, e), file=sys.stderr)
        return 2
    status, count = 0, 0
    for n, doc, perr in _documents(name, text, lines):
        count += 1
        if perr is not None:
            col, _, msg = perr.partition(": ") if perr[:1].isdigit() else ("", "", perr)
            print("%s:%d:%s error: %s" % (name, n, col + ":" if col else "", msg),
                  file=sys.stderr)
            status = 2
            continue
        for e in schema.errors(doc):
            print("%s:%d: error: %s" % (name, n, e), file=sys.stderr)
            status = max(status, 1)
    if status == 0:
        print("%s: %d document%s valid" % (name, count, "" if count == 1 else "s"))
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv))
