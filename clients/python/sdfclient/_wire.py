"""What the HTTP and the binary client share: SdfError, the tables that name modes, signs,
filter parameters and message types on the wire, and the checks that turn a caller's points and filter
parameters into what both protocols carry (docs/api.md, proto/PROTOCOL.md)."""
from __future__ import annotations

from typing import Any, Dict, Iterable, List, Literal, Mapping, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

Mode = Literal["signed", "distance", "gradient", "closest", "filtered", "filtered-gradient"]
"""A mesh query's mode: what each point's answer holds (docs/api.md)."""
Sign = Literal["auto", "pseudonormal", "winding", "raycast", "none"]
"""How a mesh query signs its distances (docs/api.md)."""
Form = Literal["npy", "octet", "json"]
"""An HTTP query's body: NumPy .npy, raw little-endian float32, or JSON."""
Interpolation = Literal["default", "trilinear", "nearest", "hermite"]
"""How a volume query reads between a baked volume's nodes (docs/volumes.md, "Evaluation"):
"default" is "hermite" on first-order volumes and "trilinear" on zero-order ones; "hermite"
on a zero-order volume is refused (422)."""
ErrorCode = Literal["EINVAL", "ENOMEM", "EIO", "EFORMAT", "EPARSE", "ETRUNC", "ELIMIT", "EEMPTY",
                   "ENONFINITE", "EINDEX", "EBVH", "ENOTFOUND", "ECANCELED", "EPROTO",
                   "EUNAUTHORIZED", "EMETHOD", "ELENGTH", "EBUSY", "EUNAVAILABLE", "ESYNTAX",
                   "ENOSPACE"]
"""The codes of sdfd's refusals (SdfError.code; docs/api.md, "Errors"); the HTTP client adds
"EUNKNOWN" for an answer that is not an error body."""
Op = Union[Mapping[str, float], Tuple[str, float]]
"""One field operation (docs/api.md): {"round": 0.05} or ("round", 0.05); the names are
redistance, offset, round, fillet and smooth."""
Result = Dict[str, npt.NDArray[Any]]
"""A query's answer: "distance" (N,) float32 always; "gradient" (N, 3) float32; "closest"
(N, 3) float32 and "triangle" (N,) uint32 in mode closest."""

MODES = {"signed": 0, "distance": 1, "gradient": 2, "closest": 3, "filtered": 4,
         "filtered-gradient": 5}
SIGNS = {"auto": 0, "pseudonormal": 1, "winding": 2, "raycast": 3, "none": 4}
WORDS = {0: 1, 1: 1, 2: 4, 3: 5, 4: 1, 5: 4}
INTERPOLATIONS = {"trilinear": 0, "nearest": 1, "hermite": 2, "default": 3}
FILTER_KEYS = ("kernel", "cap", "a", "b", "samples", "min_samples", "medial", "grid", "unsigned",
               "allow_wide_bump", "sample_gradient", "seed", "smooth")
KERNELS = {"gaussian": 0, "bump": 1}
FRAMES = {"HELLO": 0x01, "LIST_MESHES": 0x02, "QUERY": 0x03, "VOLUME_QUERY": 0x04, "AUTH": 0x05,
          "ERROR": 0x7F, "HELLO_OK": 0x81, "MESHES": 0x82, "RESULT": 0x83, "AUTH_OK": 0x85}
"""The binary protocol's message types (proto/PROTOCOL.md)."""
VOLUMES = {"sphere": 1, "box": 2, "mesh": 3}


class SdfError(Exception):
    """A request sdfd refused: .status (HTTP status), .code ("EINVAL" ...), .message."""

    status: int
    code: str
    message: str

    def __init__(self, status: int, code: str, message: str) -> None:
        """The error sdfd answered: its HTTP status (the binary protocol carries the same
        numbers), its code and its message."""
        super().__init__(f"{status} {code}: {message}")
        self.status, self.code, self.message = status, code, message


def _points(points: npt.ArrayLike) -> npt.NDArray[np.float32]:
    p = np.ascontiguousarray(points, dtype=np.float32)
    if p.ndim == 1 and p.size % 3 == 0:
        p = p.reshape(-1, 3)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError("points must have shape (N, 3)")
    return p


def _filter(filter: Optional[Mapping[str, Any]]) -> Dict[str, Any]:
    f = dict(filter or {})
    unknown = set(f) - set(FILTER_KEYS)
    if unknown:
        raise ValueError(f"unknown filter parameters {sorted(unknown)} (known: {FILTER_KEYS})")
    return f


def _ops(ops: Iterable[Op]) -> List[Dict[str, float]]:
    """Field operations as the API's JSON list [{"round": 0.05}, ...], from dicts or (name, r)
    pairs; the server checks the names and numbers."""
    if isinstance(ops, (str, bytes, Mapping)):
        raise ValueError("ops must be a list of operations, e.g. [{'round': 0.05}]")
    out: List[Dict[str, float]] = []
    for op in ops:
        if isinstance(op, Mapping) and len(op) == 1:
            out.append(dict(op))
        elif isinstance(op, (tuple, list)) and len(op) == 2 and isinstance(op[0], str):
            out.append({op[0]: op[1]})
        else:
            raise ValueError(f"an operation is {{name: r}} or (name, r), not {op!r}")
    return out


def _volume(smooth: Mapping[str, Any]) -> Tuple[str, Any]:
    """The one volume of a "smooth" dict: (kind, value)."""
    kinds = [k for k in VOLUMES if k in smooth]
    if len(kinds) != 1:
        raise ValueError('filter["smooth"] needs exactly one of "sphere", "box" or "mesh"')
    return kinds[0], smooth[kinds[0]]


def _url_filter(f: Mapping[str, Any]) -> Dict[str, Any]:
    """Filter parameters as URL arguments (booleans as 1/0, the volume as smooth_*)."""
    out = {k: (int(v) if isinstance(v, bool) else v) for k, v in f.items() if k != "smooth"}
    if "smooth" in f:
        kind, value = _volume(f["smooth"])
        out["smooth_" + kind] = value if kind == "mesh" else ",".join(repr(float(x)) for x in value)
        for k in ("depth", "scale"):
            if k in f["smooth"]:
                out["smooth_" + k] = f["smooth"][k]
    return out


def _split_words(words: npt.NDArray[np.uint32], mode: str) -> Result:
    """(N, W) uint32 words in the wire layout -> result dict."""
    out: Result = {"distance": words[:, 0].view(np.float32).copy()}
    if mode in ("gradient", "filtered-gradient"):
        out["gradient"] = words[:, 1:4].copy().view(np.float32)
    if mode == "closest":
        out["closest"] = words[:, 1:4].copy().view(np.float32)
        out["triangle"] = words[:, 4].copy()
    return out
