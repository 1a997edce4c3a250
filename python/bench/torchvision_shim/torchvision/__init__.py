"""A stand-in for torchvision, for the device check only: deepinv imports torchvision when it
is imported, but neither the physics nor the solvers spibench's tests use need it. Put on
sys.path by python/device_check.sh only when the real torchvision is missing; every name is a
placeholder that raises when used."""

import sys
import types

IMG_EXTENSIONS = (".jpg", ".jpeg", ".png", ".ppm", ".bmp", ".pgm", ".tif", ".tiff", ".webp")


class _Meta(type):
    def __getattr__(cls, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return _placeholder(name)


def _placeholder(name):
    def fail(*a, **k):
        raise ImportError(f"torchvision is not installed (placeholder {name})")

    return _Meta(name, (), {"__init__": fail, "__call__": fail})


def _module(name):
    m = types.ModuleType(name)
    m.__getattr__ = lambda attr: _placeholder(attr) if not attr.startswith("__") else (_ for _ in ()).throw(AttributeError(attr))
    m.__path__ = []
    sys.modules[name] = m
    return m


for _sub in ("transforms", "transforms.functional", "utils", "datasets", "datasets.utils",
             "datasets.folder", "io", "models", "ops"):
    _m = _module(f"torchvision.{_sub}")
    if _sub == "datasets.folder":
        _m.IMG_EXTENSIONS = IMG_EXTENSIONS
transforms = sys.modules["torchvision.transforms"]
transforms.functional = sys.modules["torchvision.transforms.functional"]
utils = sys.modules["torchvision.utils"]
datasets = sys.modules["torchvision.datasets"]
datasets.utils = sys.modules["torchvision.datasets.utils"]
datasets.folder = sys.modules["torchvision.datasets.folder"]
__version__ = "0.0+placeholder"


def __getattr__(name):
    if name.startswith("__"):
        raise AttributeError(name)
    return _placeholder(name)
