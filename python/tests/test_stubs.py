"""The type stubs (twincal/_native.pyi) against the compiled module: every public function,
class, method and property of the module is in the stubs with the same parameters and defaults,
and the stubs name nothing the module lacks."""

import ast
import inspect
from pathlib import Path

import twincal._native as native

STUBS = Path(__file__).resolve().parents[1] / "twincal" / "_native.pyi"
# A parameter without a default.
REQUIRED = "<required>"


def _stub_params(f: ast.FunctionDef, method: bool) -> list:
    args = f.args.args[1:] if method else f.args.args
    defaults = [REQUIRED] * (len(args) - len(f.args.defaults)) + [ast.literal_eval(d) for d in f.args.defaults]
    return [(a.arg, d) for a, d in zip(args, defaults)]


def _stubs() -> dict:
    out = {}
    for node in ast.parse(STUBS.read_text()).body:
        if isinstance(node, ast.FunctionDef):
            out[node.name] = _stub_params(node, False)
        elif isinstance(node, ast.ClassDef):
            out[node.name] = "class"
            for f in node.body:
                if isinstance(f, ast.FunctionDef):
                    prop = any(isinstance(d, ast.Name) and d.id == "property" for d in f.decorator_list)
                    out[f"{node.name}.{f.name}"] = "property" if prop else _stub_params(f, True)
    return out


def _native_params(obj) -> list:
    params = [p for p in inspect.signature(obj).parameters.values() if p.name != "self"]
    return [(p.name, REQUIRED if p.default is inspect.Parameter.empty else p.default) for p in params]


def _module() -> dict:
    out = {}
    for name in dir(native):
        obj = getattr(native, name)
        if name.startswith("_") or not callable(obj):
            continue
        if isinstance(obj, type):
            out[name] = "class"
            if issubclass(obj, BaseException):
                continue
            for m in dir(obj):
                attr = getattr(obj, m)
                if m.startswith("_"):
                    continue
                out[f"{name}.{m}"] = _native_params(attr) if callable(attr) else "property"
        else:
            out[name] = _native_params(obj)
    return out


def test_the_stubs_state_the_native_modules_signatures():
    stubs, module = _stubs(), _module()
    assert sorted(set(module) - set(stubs)) == [], "in the module, not in the stubs"
    assert sorted(set(stubs) - set(module)) == [], "in the stubs, not in the module"
    for name, params in module.items():
        assert stubs[name] == params, f"{name}: the stubs say {stubs[name]}, the module {params}"
