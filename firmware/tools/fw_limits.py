"""The firmware's behaviour constants (hard limits, failsafe timings, PWM frame), read from their
one source, firmware/core/limits.h, for the tests and tools that check the firmware from outside
(the simavr tests, the HIL failsafe scenario, the flight-controller emulator's tests). Nothing here
restates a value: retyping 250 ms or 950 us in a test would let the firmware and its tests drift
apart silently.

    from fw_limits import FW_LIMITS
    FW_LIMITS["kFailsafeTimeoutMs"]   # 250

Every `constexpr <integer type> kName = <expression>;` of limits.h is read; an expression may use
integer literals, + - * / and parentheses, other constants of limits.h and the generated
protocol constants `rgbd_control::kName` (protocol/control/include/rgbd_control/
control_spec_generated.h, read the same way). firmware/tests/test_fw_limits.py compiles limits.h
and checks this reader gets every constant and every value the compiler gets. Standard library only.
"""

from __future__ import annotations

import ast
import operator
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[2]
LIMITS_H = ROOT / "firmware" / "core" / "limits.h"
CONTROL_SPEC_H = (
    ROOT / "protocol" / "control" / "include" / "rgbd_control" / "control_spec_generated.h"
)

#: A constexpr integer constant definition (one per line in these headers).
DEFINITION_RE = re.compile(
    r"^\s*constexpr\s+(?:u?int(?:8|16|32|64)_t|size_t)\s+(k\w+)\s*=\s*([^;]+);", re.M
)
_SUFFIX_RE = re.compile(r"\b(\d+)(?:UL|ULL|U|L)\b")
_OPS = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.FloorDiv: operator.floordiv,
}


def _evaluate(expr: str, known: dict[str, int], where: str) -> int:
    """Integer value of a C++ constant expression of the subset above (C '/' on non-negative
    integers is floor division)."""
    py = _SUFFIX_RE.sub(r"\1", expr.strip()).replace("rgbd_control::", "rgbd_control__")
    py = py.replace("/", "//")

    def ev(node: ast.AST) -> int:
        if isinstance(node, ast.Constant) and isinstance(node.value, int):
            return node.value
        if isinstance(node, ast.Name) and node.id in known:
            return known[node.id]
        if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            return _OPS[type(node.op)](ev(node.left), ev(node.right))
        raise ValueError(f"{where}: cannot evaluate {expr!r} ({ast.dump(node)})")

    return ev(ast.parse(py, mode="eval").body)


def parse(text: str, known: dict[str, int] | None = None, where: str = "header") -> dict[str, int]:
    """Every constant of `text`, in definition order; `known` resolves names it refers to."""
    env = dict(known or {})
    out: dict[str, int] = {}
    for name, expr in DEFINITION_RE.findall(text):
        value = _evaluate(expr, env, f"{where} {name}")
        env[name] = out[name] = value
    return out


def load(
    limits_h: pathlib.Path = LIMITS_H, control_spec_h: pathlib.Path = CONTROL_SPEC_H
) -> dict[str, int]:
    """The constants of limits.h by name (kFailsafeTimeoutMs, kFailsafeThrottleUs, ...)."""
    protocol = parse(control_spec_h.read_text(), where=control_spec_h.name)
    known = {f"rgbd_control__{k}": v for k, v in protocol.items()}
    return parse(limits_h.read_text(), known, where=limits_h.name)


FW_LIMITS = load()
