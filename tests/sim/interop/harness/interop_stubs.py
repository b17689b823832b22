"""Stand-ins for LeRobot's heavy imports (torch, cv2, ...) that its motor and robot code does not use.

Installed as a meta-path finder *only in the interop test harness*: any import of a listed top-level package
(and its submodules) gets a module whose every attribute is a stand-in class. Using one for real raises.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import os
import sys
import types

STUBBED = (
    "torch",
    "torchvision",
    "cv2",
    "huggingface_hub",
    "safetensors",
    "einops",
    "gymnasium",
    "PIL",
    "datasets",
    "av",
    "pyarrow",
    "pandas",
    "accelerate",
    "transformers",
    "placo",
    "rerun",
    "wandb",
    "jsonlines",
    "imageio",
)


class _StubMeta(type):
    def __getattr__(cls, name: str):
        if name.startswith("__") and name.endswith("__"):
            raise AttributeError(name)
        return _stub_class(f"{cls.__qualname__}.{name}")

    def __or__(cls, other):
        return cls

    def __ror__(cls, other):
        return cls

    def __getitem__(cls, item):
        return cls


def _stub_class(name: str) -> type:
    def call(self, *args, **kwargs):
        if len(args) == 1 and callable(args[0]) and not kwargs:
            return args[0]  # used as a decorator
        return _stub_class(f"{name}()")()

    def enter(self):
        return self

    def exit_(self, *exc):
        return False

    return _StubMeta(
        name, (), {"__call__": call, "__enter__": enter, "__exit__": exit_, "__module__": "interop_stubs"}
    )


VALUES = {
    # LeRobot derives its calibration folder from huggingface_hub's HF_HOME (same rule as huggingface_hub)
    "huggingface_hub.constants": {
        "HF_HOME": os.path.expanduser(
            os.getenv("HF_HOME", os.path.join(os.getenv("XDG_CACHE_HOME", "~/.cache"), "huggingface"))
        ),
    },
}


class _StubModule(types.ModuleType):
    def __getattr__(self, name: str):
        if name.startswith("__") and name.endswith("__"):
            raise AttributeError(name)
        return _stub_class(f"{self.__name__}.{name}")


class _Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, fullname, path, target=None):
        if fullname.split(".")[0] in STUBBED:
            return importlib.machinery.ModuleSpec(fullname, self, is_package=True)
        return None

    def create_module(self, spec):
        mod = _StubModule(spec.name)
        mod.__path__ = []
        mod.__version__ = "0.0+interop-stub"
        mod.__dict__.update(VALUES.get(spec.name, {}))
        return mod

    def exec_module(self, module):
        pass


sys.meta_path.insert(0, _Finder())
