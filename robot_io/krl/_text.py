"""KRL text rules for the writer (private helper of ``robot_io.krl``): identifiers, comments,
numbers (KUKA_IO.md §1.1, §1.3).

* Identifiers: at most :data:`MAX_IDENTIFIER` characters, letters A–Z, digits, ``_`` and ``$``, not
  starting with a digit, not a keyword. Module (file) names are stricter: no ``$`` (``$`` names are
  the controller's system variables).
* Comments: plain printable ASCII. Non-ASCII text is transliterated: a small table for the Greek
  letters and symbols our reports use (``γ`` → ``gamma``, ``°`` → ``deg``, ``µ`` → ``u``, ``≤`` →
  ``<=``, ``×`` → ``x`` …), then Unicode NFKD decomposition with the combining marks dropped
  (``é`` → ``e``); whatever is still not ASCII is dropped. Control characters become spaces.
* Numbers: fixed point, never exponents; ``-0`` is written as ``0``.
"""

from __future__ import annotations

import math
import re
import unicodedata

__all__ = [
    "KEYWORDS",
    "MAX_IDENTIFIER",
    "ascii_comment",
    "fixed",
    "identifier_problem",
    "module_name_problem",
    "real_literal",
    "sanitize_identifier",
]

#: Longest KRL identifier [characters] (KUKA_IO.md §1.1).
MAX_IDENTIFIER = 24
#: Most decimals a REAL literal may need to read back as the same double (17 significant digits
#: of a number below 1e-3 need up to 20 decimals; beyond that the value is not a feed).
_MAX_REAL_DECIMALS = 24

#: KRL keywords (and motion/approximation words) that must not be used as names.
KEYWORDS = frozenset("""
AND ANIN ANOUT AXIS B_AND B_EXOR B_NOT B_OR BOOL BRAKE C_DIS C_ORI C_PTP C_VEL CA CASE CCLOSE
CHAR CIRC CIRC_REL CONST CONTINUE CREAD CWRITE DECL DEF DEFAULT DEFDAT DEFFCT DELAY DISTANCE DO
E6AXIS E6POS ELSE END ENDDAT ENDFCT ENDFOR ENDIF ENDLOOP ENDSPLINE ENDSWITCH ENDWHILE ENUM EXIT
EXOR EXT EXTFCT FALSE FOR FRAME GLOBAL GOTO HALT IF IMPORT IN INT INTERRUPT IS LIN LIN_REL LOOP
MAXIMUM MINIMUM NOT OFF ON OR OUT POS PRIO PTP PTP_REL PUBLIC PULSE REAL REPEAT RESUME RETURN SCIRC
SEC SIGNAL SLIN SPL SPLINE SPTP STEP STRUC SWITCH THEN TO TRIGGER TRUE UNTIL WAIT WHEN WHILE
""".split())

_IDENT = re.compile(r"[A-Za-z_$][A-Za-z0-9_$]*\Z")
_MODULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")

#: Transliterations tried before NFKD (Greek letters and symbols of our reports).
_TRANSLIT = {
    "α": "alpha", "β": "beta", "γ": "gamma", "δ": "delta", "ε": "eps", "θ": "theta",
    "λ": "lambda", "μ": "u", "µ": "u", "π": "pi", "σ": "sigma", "τ": "tau", "φ": "phi",
    "ω": "omega", "Δ": "Delta", "Σ": "Sigma", "Ω": "Omega", "°": "deg", "±": "+/-", "×": "x",
    "·": "*", "÷": "/", "≤": "<=", "≥": ">=", "≠": "<>", "≈": "~", "→": "->", "←": "<-",
    "–": "-", "—": "-", "−": "-", "‘": "'", "’": "'", "“": '"', "”": '"', "…": "...",
    "²": "^2", "³": "^3", "√": "sqrt", "∞": "inf", "ß": "ss", "Æ": "AE", "æ": "ae", "Ø": "O",
    "ø": "o", "Œ": "OE", "œ": "oe", "Ł": "L", "ł": "l",
}


def identifier_problem(name: str) -> str | None:
    """Why ``name`` is not a valid KRL identifier, or ``None`` when it is."""
    if not name:
        return "is empty"
    if len(name) > MAX_IDENTIFIER:
        return f"has {len(name)} characters; KRL allows at most {MAX_IDENTIFIER}"
    if not name.isascii() or not _IDENT.match(name):
        return ("may hold only letters A-Z, digits, '_' and '$' and must not start with a "
                "digit")
    if name.upper() in KEYWORDS:
        return "is a KRL keyword"
    return None


def module_name_problem(name: str) -> str | None:
    """Why ``name`` cannot be a KRL module (file) name, or ``None``."""
    p = identifier_problem(name)
    if p is not None:
        return p
    if not _MODULE.match(name):
        return "must not contain '$' (reserved for system variables)"
    return None


def sanitize_identifier(text: str, fallback: str = "CCT_PROG", max_len: int = MAX_IDENTIFIER) -> str:
    """A valid module name made from free text (e.g. a job name): transliterated, every other
    character replaced by ``_``, a leading digit prefixed with ``P``, cut to ``max_len``; the
    ``fallback`` when nothing usable is left."""
    s = ascii_comment(text).strip()
    s = re.sub(r"[^A-Za-z0-9_]+", "_", s).strip("_")
    if not s:
        s = fallback
    if s[0].isdigit():
        s = "P" + s
    s = s[:max_len].rstrip("_") or fallback[:max_len]
    if s.upper() in KEYWORDS:
        s = (s + "_P")[:max_len]
    return s


def ascii_comment(text: str) -> str:
    """``text`` as one line of printable ASCII (see the module docstring)."""
    out = []
    for ch in text:
        if ch in _TRANSLIT:
            out.append(_TRANSLIT[ch])
        elif ch.isascii():
            out.append(ch if ch.isprintable() else " ")
        else:
            base = "".join(c for c in unicodedata.normalize("NFKD", ch)
                           if c.isascii() and c.isprintable())
            out.append(base)
    return "".join(out)


def fixed(value: float, decimals: int) -> str:
    """``value`` in fixed point with ``decimals`` decimals; ``-0.000`` becomes ``0.000``."""
    s = f"{value:.{decimals}f}"
    if s.startswith("-") and not s.strip("-0."):
        s = s[1:]
    return s


def real_literal(value: float, min_decimals: int) -> str:
    """The shortest fixed-point text with at least ``min_decimals`` decimals that reads back as
    exactly ``value`` (a finite float). Raises ``ValueError`` when no such text exists within
    the decimals a feed can need."""
    if not math.isfinite(value):
        raise ValueError(f"{value!r} is not a finite number")
    for d in range(min_decimals, _MAX_REAL_DECIMALS + 1):
        s = fixed(value, d)
        if float(s) == value:
            return s
    raise ValueError(f"{value!r} needs more than {_MAX_REAL_DECIMALS} decimals")
