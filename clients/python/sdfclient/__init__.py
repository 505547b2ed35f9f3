"""sdfclient - Python client for sdfd (standard library + numpy only).

    import numpy as np, sdfclient
    c = sdfclient.Client("http://127.0.0.1:8080")
    c.meshes()                                   # [{'name': 'demo', 'triangles': 12288, ...}]
    r = c.query("demo", np.zeros((5, 3)), mode="gradient")
    r["distance"], r["gradient"]                 # float32 arrays (5,) and (5, 3)

    b = sdfclient.BinaryClient("127.0.0.1", 9090)
    r = b.query("demo", points, mode="closest")  # distance, closest, triangle
    rs = b.query_many([("demo", p1), ("demo", p2)])   # pipelined on one connection

    # the convolution-filtered field (docs/filtered.md); filter= takes its parameters
    r = c.query("demo", points, mode="filtered-gradient", filter={"samples": 32, "seed": 1})

    # baked volumes (docs/volumes.md): bake, wait, download, query
    job = c.bake("demo", volume="knot", resolution=64, order=1)
    c.wait(job)
    grid = c.download("knot", format="npy")      # float32 (64, 64, 64, 4)
    r = c.query_volume("knot", points, gradient=True)   # interpolation="default": hermite
    c.wait(c.volume_ops("knot", [("round", 0.05)], volume="knot_round"))  # field operations

Results are dicts of numpy arrays: "distance" always (the filtered value g in the filtered
modes); "gradient" (modes gradient and filtered-gradient); "closest" and "triangle" (mode
closest). Errors raise SdfError with the HTTP status, the error code (e.g. "ENOTFOUND") and
the server's message.

The package ships its type hints (py.typed); Mode, Sign, Form, Interpolation, Op and Result
name the types of the arguments and answers, ErrorCode the codes SdfError carries.
"""
from ._binary import BinaryClient
from ._http import Client
from ._wire import (FILTER_KEYS, INTERPOLATIONS, MODES, SIGNS, ErrorCode, Form, Interpolation,
                    Mode, Op, Result, SdfError, Sign)

__version__ = "0.1.0"

__all__ = ["Client", "BinaryClient", "SdfError", "Mode", "Sign", "Form", "Interpolation", "Op",
           "Result", "ErrorCode", "MODES", "SIGNS", "INTERPOLATIONS", "FILTER_KEYS", "__version__"]

# The classes are used as sdfclient.X: say so in their reprs, help() and tracebacks.
for _cls in (Client, BinaryClient, SdfError):
    _cls.__module__ = __name__
del _cls
