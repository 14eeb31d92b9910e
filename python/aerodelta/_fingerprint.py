"""The data's fingerprint: one SHA-256 of a frame, the same wherever aerodelta records it.

A fitted model's provenance (``data_sha256``) and the evidence pack of a frame (its "data
SHA-256" when no files were read) both use :func:`data_sha256`, so a pack built from the frame
a model was fitted on shows the digest in the model's file.
"""

from __future__ import annotations

import hashlib

import numpy as np
import polars as pl


def data_sha256(data: pl.DataFrame) -> str:
    """SHA-256 (hex) of a frame's shape, column names and values.

    The bytes hashed: ``str(data.shape)``; then, per column in name order, its name and its
    values: numeric columns as their float64 bytes (nulls as NaN), other columns as the text of
    each value (``str``: nulls as ``"None"``, booleans as ``True``/``False``) joined by U+001F.
    The row order counts; the column order does not.
    """
    h = hashlib.sha256()
    h.update(str(data.shape).encode())
    for c in sorted(data.columns):
        h.update(c.encode())
        s = data[c]
        if s.dtype.is_numeric():
            # float64 bytes, nulls as NaN; hashed from the array's buffer (no copy to bytes)
            if s.dtype != pl.Float64:
                s = s.cast(pl.Float64)
            if s.null_count():
                s = s.fill_null(np.nan)
            h.update(np.ascontiguousarray(s.to_numpy()))
        elif s.dtype in (pl.Utf8, pl.Categorical) or isinstance(s.dtype, pl.Enum):  # fast path
            h.update(s.cast(pl.Utf8).fill_null("None").str.join("\x1f")[0].encode())
        elif s.dtype == pl.Boolean:  # the text of str(bool), as below, without a Python list
            text = s.replace_strict({True: "True", False: "False"}, return_dtype=pl.Utf8)
            h.update(text.fill_null("None").str.join("\x1f")[0].encode())
        else:
            h.update("\x1f".join(map(str, s.to_list())).encode())
    return h.hexdigest()
