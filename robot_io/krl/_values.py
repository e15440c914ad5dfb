"""KRL variables: scopes, declarations, look-up and assignment (private helper of
``robot_io.krl.reader``).

Scopes, innermost first: the running routine's locals, the module's ``.dat``, the globals (``DECL
GLOBAL`` items of any ``.dat`` read so far, all items of ``global_dat`` files, and variables a
program assigns without declaring — KUKA's ``$config.dat`` items such as ``PDAT_ACT``). Values the
reader cannot evaluate become :class:`Unknown`; reading one where a number or position is needed is
a :class:`~robot_io.krl._syntax.LineError` (category ``unknown_value``), an undeclared name one of
category ``undeclared``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import Any

from robot_io.krl._program import Routine, SrcFile, Stmt
from robot_io.krl._syntax import Aggregate, Cursor, LineError, Ref, parse_value
from robot_io.options import fix

__all__ = [
    "CART",
    "Ctx",
    "Current",
    "Module",
    "Unknown",
    "Var",
    "Variables",
    "expect_end",
]

#: Components of a Cartesian KRL position/frame (mm, deg).
CART = ("X", "Y", "Z", "A", "B", "C")

_CART_EXAMPLE = "={X …,Y …,Z …,A …,B …,C …}"
_AXIS_EXAMPLE = "={A1 …,A2 …,A3 …,A4 …,A5 …,A6 …}"
#: How a message suggests setting an element of an array of each type.
_EXAMPLES = {"FRAME": _CART_EXAMPLE, "POS": _CART_EXAMPLE, "E6POS": _CART_EXAMPLE,
             "AXIS": _AXIS_EXAMPLE, "E6AXIS": _AXIS_EXAMPLE}


class Unknown:
    """A value the reader cannot know (set at run time, or by an expression it does not evaluate)."""

    __slots__ = ("reason",)

    def __init__(self, reason: str) -> None:
        self.reason = reason


class Current:
    """``$POS_ACT`` / ``$AXIS_ACT``: wherever the robot is."""

    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name


@dataclass
class Var:
    """A declared (or implicitly assigned) variable; arrays keep their elements in ``elems``;
    ``source`` is where it was declared (``file:line``, empty when not declared)."""

    type: str | None
    value: Any
    dims: tuple[int, ...] = ()
    elems: dict[tuple[int, ...], Any] = field(default_factory=dict)
    source: str = ""

    def check_index(self, ref: Ref) -> None:
        """KRL arrays run from 1 to their declared size: anything else is an error."""
        if not self.dims or ref.index is None or len(ref.index) != len(self.dims):
            return
        for k, n in zip(ref.index, self.dims, strict=True):
            if not 1 <= k <= n:
                size = ",".join(map(str, self.dims))
                raise LineError(ref.col, f"{ref.text}: the index {k} is outside the array "
                                f"{ref.name}[{size}] (declared at {self.source or 'its DECL'}; "
                                "KRL indices run from 1 to the size)", "unknown_value")

    def unset(self, ref: Ref) -> Unknown:
        """The value of an element the program never sets."""
        where = f"declared at {self.source}, " if self.source else ""
        example = _EXAMPLES.get(self.type or "", " = …")
        index = ",".join(map(str, ref.index or ()))
        return Unknown(f"{ref.name}[{index}] is {where}never set in the program: give it a "
                       f"value, e.g. a line {ref.name}[{index}]{example} in the .dat")


@dataclass
class Module:
    """A loaded ``.src`` module and the variables of its ``.dat``."""

    name: str
    path: str
    src: SrcFile
    vars: dict[str, Var] = field(default_factory=dict)


@dataclass
class Ctx:
    """Where a statement runs: its module, routine (``None`` in a ``.dat``) and locals."""

    module: Module
    routine: Routine | None
    locals: dict[str, Var] = field(default_factory=dict)


def expect_end(cur: Cursor) -> None:
    """Fail unless every token of the statement was read."""
    t = cur.peek()
    if t is not None:
        raise LineError(t.col, f"unexpected {t.text!r} after the value")


class Variables:
    """The global scope and the rules for reading and writing variables."""

    def __init__(self) -> None:
        self.globals: dict[str, Var] = {
            "BASE_DATA": Var("FRAME", Unknown("not set"), (32,)),
            "TOOL_DATA": Var("FRAME", Unknown("not set"), (16,)),
        }

    def lookup(self, ctx: Ctx, name: str) -> Var | None:
        """The variable ``name`` visible here: routine locals, module .dat, then globals."""
        return ctx.locals.get(name) or ctx.module.vars.get(name) or self.globals.get(name)

    def index(self, ctx: Ctx, cur: Cursor) -> Any:
        """An array index expression at the cursor."""
        return parse_value(cur, partial(self.resolve, ctx))

    def resolve(self, ctx: Ctx, ref: Ref) -> Any:
        """Value of a reference; LineError when undeclared or not known."""
        name = ref.name
        plain = ref.index is None and not ref.fields
        if name == "$NULLFRAME" and plain:
            return Aggregate("FRAME", dict.fromkeys(CART, 0.0))
        if name in ("$POS_ACT", "$AXIS_ACT") and plain:
            return Current(name)
        var = self.lookup(ctx, name)
        if var is None:
            if name.startswith("$"):
                raise LineError(ref.col, f"the reader does not know the value of the system "
                                f"variable {ref.text}; use a literal or a variable declared in "
                                "the .dat", "unknown_value")
            raise LineError(ref.col, f"undeclared variable {ref.text}: declare it in "
                            f"{ctx.module.name}.dat (e.g. DECL E6POS {name}={{X 0,Y 0,Z 0,A 0,B 0,"
                            f"C 0}} or DECL REAL {name}=0.002), or pass the .dat that declares it "
                            f"with {fix('global_dat', ['its.dat'])}", "undeclared")
        if ref.index:
            var.check_index(ref)
            value = var.elems.get(ref.index)
            if value is None:
                value = var.unset(ref)
        else:
            value = var.value
        for f in ref.fields:
            if isinstance(value, Aggregate):
                if f not in value.fields:
                    raise LineError(ref.col, f"{ref.text}: the value has no component {f}",
                                    "unknown_value")
                value = value.fields[f]
        if isinstance(value, Unknown):
            raise LineError(ref.col, f"the value of {ref.text} is not known here "
                            f"({value.reason})", "unknown_value")
        return value

    def value_or_unknown(self, ctx: Ctx, cur: Cursor, st: Stmt) -> Any:
        """A value at the cursor; what the reader does not evaluate becomes :class:`Unknown` and
        is skipped up to the next top-level ``,`` or closing bracket (syntax errors raise)."""
        start = cur.i
        try:
            v = parse_value(cur, partial(self.resolve, ctx))
        except LineError as e:
            if e.category == "syntax":
                raise
            v = Unknown(f"set at {st.file}:{st.line} from {e.reason}")
        t = cur.peek()
        if t is not None and t.text not in (",", ")", "]", "}"):
            # comparisons, logic, function calls (brackets are balanced on the line)
            depth = 0
            while t is not None:
                if t.kind == "sym" and t.text in "([{":
                    depth += 1
                elif t.kind == "sym" and t.text in ")]}":
                    if depth == 0:
                        break
                    depth -= 1
                elif t.text == "," and depth == 0:
                    break
                cur.i += 1
                t = cur.peek()
            col = st.tokens[start].col if start < len(st.tokens) else 0
            v = Unknown(f"set at {st.file}:{st.line} by an expression the reader does not "
                        f"evaluate (from column {col})")
        return v

    def declare(self, ctx: Ctx, scope: dict[str, Var], st: Stmt) -> None:
        """``DECL [GLOBAL] [CONST] TYPE NAME[dims] [= value] {, ...}`` (``DECL`` optional)."""
        cur = Cursor(st.tokens, st.end_col)
        cur.accept("DECL")
        is_global = False
        while True:
            if cur.accept("GLOBAL"):
                is_global = True
            elif cur.accept("CONST") is None:
                break
        typ = cur.next("a type such as REAL or E6POS")
        if typ.kind != "name":
            raise LineError(typ.col, f"expected a type such as REAL or E6POS, found {typ.text!r}")
        while True:
            nm = cur.next("a variable name")
            if nm.kind != "name":
                raise LineError(nm.col, f"expected a variable name, found {nm.text!r}")
            dims: list[int] = []
            if cur.accept("["):
                while True:
                    d = cur.next("an array size")
                    if d.kind != "num" or d.value != int(d.value) or d.value < 0:
                        raise LineError(d.col, "an array size must be a whole number")
                    dims.append(int(d.value))
                    if cur.accept("]"):
                        break
                    cur.expect(",", "',' or ']'")
            var = Var(typ.upper, Unknown(f"{nm.text} is declared at {st.file}:{st.line} "
                                         "without a value"), tuple(dims),
                      source=f"{st.file}:{st.line}")
            if cur.accept("="):
                var.value = self.value_or_unknown(ctx, cur, st)
            (self.globals if is_global else scope)[nm.upper] = var
            if cur.accept(",") is None:
                break
        t = cur.peek()
        if t is not None:
            raise LineError(t.col, f"unexpected {t.text!r} in the declaration")

    def assign(self, ctx: Ctx, st: Stmt, ref: Ref, cur: Cursor,
               scope: dict[str, Var] | None) -> None:
        """Store into a user variable (an undeclared one becomes a global, or goes to ``scope``)."""
        value = self.value_or_unknown(ctx, cur, st)
        expect_end(cur)
        var = self.lookup(ctx, ref.name)
        if var is None:
            var = Var(None, Unknown(f"{ref.name} is not declared in the program"))
            (self.globals if scope is None else scope)[ref.name] = var
        if ref.index:
            var.check_index(ref)
            old = var.elems.get(ref.index, Unknown("never set"))
            var.elems[ref.index] = _merge(old, ref.fields, value)
        else:
            var.value = _merge(var.value, ref.fields, value)

    def set_data(self, ctx: Ctx, scope: dict[str, Var], new_scope: dict[str, Var] | None,
                 st: Stmt) -> None:
        """A data line pre-parsed by :func:`~robot_io.krl._syntax.fast_data`: the same as
        :meth:`declare` (into ``scope``) or :meth:`assign` (a new name goes to ``new_scope``)."""
        data = st.data
        if data is None:
            raise ValueError("set_data needs a statement with a data form")
        typ, is_global, name, index, comps, col, lit_type = data
        value = Aggregate(lit_type, dict(comps), col)
        if typ is not None:
            (self.globals if is_global else scope)[name] = Var(typ, value,
                                                               source=f"{st.file}:{st.line}")
            return
        var = self.lookup(ctx, name)
        if var is None:
            var = Var(None, Unknown(f"{name} is not declared in the program"))
            (self.globals if new_scope is None else new_scope)[name] = var
        if index is None:
            var.value = _merge(var.value, (), value)
            return
        key = (index,)
        var.check_index(Ref(name, key, (), 1 + len(st.code) - len(st.code.lstrip()),
                            f"{name}[{index}]"))
        var.elems[key] = _merge(var.elems.get(key), (), value)


def _merge(old: Any, fields: tuple[str, ...], value: Any) -> Any:
    """KRL assignment: an aggregate updates only the components it names."""
    if not fields:
        if isinstance(old, Aggregate) and isinstance(value, Aggregate):
            return Aggregate(old.type_name, {**old.fields, **value.fields}, value.col)
        return value
    if len(fields) == 1 and isinstance(old, Aggregate):
        return Aggregate(old.type_name, {**old.fields, fields[0]: value}, old.col)
    return Unknown("a component was set but the rest of the value is not known")
