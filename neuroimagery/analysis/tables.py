"""Reading a results table back (``trials.csv``, ``individuals.csv``) for pooling, refused unless
the file is whole."""
from __future__ import annotations

import io
from pathlib import Path
from typing import Sequence

import pandas as pd

from ..core.errors import UserInputError


def read_whole_csv(path: Path, required: Sequence[str], numeric: Sequence[str], filled: Sequence[str]) -> pd.DataFrame:
    """The rows of ``path``, refused (one :class:`UserInputError` naming the file) unless it is
    readable, has the ``required`` columns, ends with a complete line, has at least one row, its
    ``numeric`` columns are numbers and no ``filled`` field is empty. A missing file raises
    ``FileNotFoundError`` for the caller to name."""
    try:
        raw = Path(path).read_bytes()
    except FileNotFoundError:
        raise
    except OSError as err:
        raise UserInputError(f"{path}: cannot read ({err.strerror or err})") from None
    if not raw.strip():
        raise UserInputError(f"{path}: empty file")
    try:
        df = pd.read_csv(io.BytesIO(raw))
    except ValueError as err:  # pandas' parser and decoding errors
        raise UserInputError(f"{path}: not a readable CSV file ({str(err).strip().splitlines()[0]})") from None
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise UserInputError(f"{path}: missing columns {', '.join(missing)}")
    if not raw.endswith(b"\n"):  # the run's writer ends every row with one
        raise UserInputError(f"{path}: cut short (the last line is incomplete)")
    if df.empty:
        raise UserInputError(f"{path}: no rows (header only)")
    for col in numeric:
        if not pd.api.types.is_numeric_dtype(df[col]):
            raise UserInputError(f"{path}: column {col} is not numeric")
    empty = df[list(filled)].isna().any(axis=1)
    if empty.any():
        raise UserInputError(f"{path}: line {int(empty.to_numpy().argmax()) + 2} has empty fields")
    return df
