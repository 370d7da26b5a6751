"""Datasets between the extension module and Python: the NetCDF structure ebiv's writer
holds (dims, variables with attributes, global attributes) turned into an
``xarray.Dataset`` exactly as ``xarray.open_dataset`` reads ebiv's NetCDF file, or into a
dict of NumPy arrays; and back, for ``ebiv.write`` and ``ebiv.assess``."""

from __future__ import annotations

from typing import Any, Dict

import numpy as np

#: Units of ebiv's CF time coordinate (the camera clock counted from a reference date).
TIME_UNITS = "microseconds since 1970-01-01 00:00:00"

#: The NetCDF type of each variable ebiv writes; other variables are float64.
_TYPES = {
    "u": np.float32,
    "v": np.float32,
    "u_unc": np.float32,
    "v_unc": np.float32,
    "peak": np.float32,
    "peak_ratio": np.float32,
    "status": np.int16,
    "event_count": np.int32,
    "slab_us": np.int32,
    # Derived quantities (ebiv.derive).
    "vorticity": np.float32,
    "divergence": np.float32,
    "e_xx": np.float32,
    "e_yy": np.float32,
    "e_xy": np.float32,
    "swirling_strength": np.float32,
}

#: Dimensions of the variables that do not span (time, y, x).
_DIMS = {"time": ("time",), "y": ("y",), "x": ("x",), "y_px": ("y",), "x_px": ("x",)}


def have_xarray() -> bool:
    try:
        import xarray  # noqa: F401
    except ImportError:
        return False
    return True


def to_xarray(raw: Dict[str, Any], decode_times: bool = True):
    """An ``xarray.Dataset`` of the structure ``raw``, with the variables, attributes and
    units of ebiv's NetCDF file; ``decode_times`` as in ``xarray.open_dataset``."""
    import xarray as xr

    coords, data_vars = {}, {}
    for name, dims, array, attrs in raw["variables"]:
        variable = xr.Variable(dims, array, dict(attrs))
        if dims == (name,):
            coords[name] = variable
        else:
            data_vars[name] = variable
    ds = xr.Dataset(data_vars, coords, dict(raw["attrs"]))
    return xr.decode_cf(ds, decode_times=decode_times)


def to_dict(raw: Dict[str, Any]) -> Dict[str, Any]:
    """The structure ``raw`` as ``{name: array}``, plus ``attrs`` (global attributes) and
    ``variable_attrs`` (``{name: attributes}``)."""
    out: Dict[str, Any] = {}
    variable_attrs = {}
    for name, _dims, array, attrs in raw["variables"]:
        out[name] = array
        variable_attrs[name] = dict(attrs)
    out["attrs"] = dict(raw["attrs"])
    out["variable_attrs"] = variable_attrs
    return out


def _time_values(values: np.ndarray, attrs: dict, encoding: dict) -> np.ndarray:
    """Decoded dates back to µs of the camera clock, with their CF units restored."""
    if np.issubdtype(values.dtype, np.datetime64):
        attrs.setdefault("units", encoding.get("units", TIME_UNITS))
        attrs.setdefault("calendar", encoding.get("calendar", "proleptic_gregorian"))
        # Integer µs first: through a float division, µs of the Unix epoch lose their last
        # digits.
        return values.astype("datetime64[us]").astype(np.int64).astype(np.float64)
    return values


def from_field(field: Any) -> Dict[str, Any]:
    """The structure of a field given as an ``xarray.Dataset`` (as ``ebiv.process`` returns
    it, or read from a NetCDF file) or as the dict ``to_dict`` makes."""
    if hasattr(field, "data_vars"):
        names = list(field.coords) + list(field.data_vars)
        columns = {n: np.asarray(field[n].values) for n in names}
        attrs = {n: dict(field[n].attrs) for n in names}
        encodings = {n: dict(field[n].encoding) for n in names}
        global_attrs = dict(field.attrs)
    elif isinstance(field, dict) and "u" in field:
        columns = {n: np.asarray(a) for n, a in field.items() if n not in ("attrs", "variable_attrs")}
        attrs = {n: dict(field.get("variable_attrs", {}).get(n, {})) for n in columns}
        encodings = {n: {} for n in columns}
        global_attrs = dict(field.get("attrs", {}))
    else:
        raise TypeError(
            "give a field as an xarray.Dataset, a dict of arrays from ebiv.process, or a path"
        )
    for needed in ("time", "y", "x", "u", "v"):
        if needed not in columns:
            raise ValueError(f"invalid parameter `field`: the field has no `{needed}`")
    sizes = {d: columns[d].size for d in ("time", "y", "x")}
    variables = []
    for name, values in columns.items():
        dims = _DIMS.get(name, ("time", "y", "x"))
        if name == "time":
            values = _time_values(values, attrs[name], encodings[name])
        values = np.ascontiguousarray(values, dtype=_TYPES.get(name, np.float64))
        expected = tuple(sizes[d] for d in dims)
        if values.shape != expected:
            raise ValueError(
                f"invalid parameter `field`: `{name}` has shape {values.shape}, "
                f"not {expected} of its dimensions {dims}"
            )
        variables.append((name, dims, values, attrs[name]))
    return {"dims": list(sizes.items()), "variables": variables, "attrs": global_attrs}
