"""The envelope analysis on a DataFrame: per-scenario thresholds, severity bands, the ODD entry.

    >>> import fogline.envelope
    >>> env = fogline.envelope.analyze(pairs_df, bootstrap=2000)        # doctest: +SKIP
    >>> env.odd                                                          # doctest: +SKIP

``analyze`` takes a pandas or polars DataFrame or a pyarrow Table with one row per clip and
perturbed condition (the columns of ``docs/envelope.md``: ``clip_id``, ``scenario``,
``attack`` or ``condition``, ``ade_clean``, ``ade_attacked``, ``l2``, ``coc_clean``,
``coc_attacked``, ...). The table reaches the analysis through the Arrow C stream interface,
without a CSV round trip; the result is the same as the CLI's ``envelope.json`` for the same
rows and parameters (only ``input`` differs: there is no file).
"""

import json

from ._fogline import envelope_analyze as _analyze
from ._fogline import envelope_defaults as _defaults
from ._fogline import envelope_synthetic_csv as _synthetic_csv

__all__ = ["analyze", "defaults", "write_synthetic_csv", "Envelope"]

_RULES = ("first-violation", "max-passing")


def defaults():
    """The analysis parameters and their defaults (the envelope paper's), as a dict."""
    params = json.loads(_defaults())
    params.pop("taxonomy", None)  # given as taxonomy="auto" | "paper" | "data"
    return params


def _arrow(table):
    """An object exporting the Arrow C stream interface for ``table``."""
    if hasattr(table, "__arrow_c_stream__"):
        return table
    module = type(table).__module__
    if module.startswith("pandas"):
        try:
            import pyarrow
        except ImportError as e:
            raise TypeError(
                "table: a pandas DataFrame is handed over through pyarrow: pip install pyarrow"
            ) from e
        return pyarrow.Table.from_pandas(table, preserve_index=False)
    raise TypeError(
        "table: expected a pandas or polars DataFrame or a pyarrow Table, "
        f"got {type(table).__name__}"
    )


def analyze(table, *, taxonomy="auto", allow_incomplete=False, name="<DataFrame>", **params):
    """Analyse a pairs table (sections 3-7 and tables 1-5 of the envelope paper).

    Args:
        table: a pandas or polars DataFrame or a pyarrow Table (or anything with
            ``__arrow_c_stream__``), one row per clip x perturbed condition.
        taxonomy: ``"auto"`` (the paper's seven classes when the data uses any of them),
            ``"paper"`` or ``"data"`` (the labels found in the data), as the CLI's
            ``--taxonomy``.
        allow_incomplete: accept clips that lack some conditions.
        name: stands for the file name in error messages and in ``input.path``.
        **params: analysis parameters by name, as in :func:`defaults` (``budgets``,
            ``headline_budget``, ``rule``, ``bootstrap``, ``bootstrap_method``, ``seed``,
            ``bands`` (``"auto"`` or a number of bands), ``pi_star``, ``sigma_op``,
            ``min_clips``, ``odd_family``, ...). Unnamed ones keep the paper's defaults.

    Returns:
        An :class:`Envelope`.

    Raises:
        TypeError: ``table`` is not a table, or a parameter name is unknown.
        ValueError: a bad cell (naming the row and column, e.g. a NaN ADE), a missing
            column, or an invalid parameter.
    """
    known = defaults()
    unknown = sorted(set(params) - set(known))
    if unknown:
        raise TypeError(
            f"unknown analysis parameter(s) {', '.join(unknown)}; expected some of "
            f"{', '.join(sorted(known))}"
        )
    if "bands" in params and params["bands"] != "auto":
        k = params["bands"]
        if isinstance(k, bool) or not isinstance(k, int):
            raise TypeError(f'bands: expected "auto" or a whole number of bands, got {k!r}')
        params["bands"] = {"fixed": k}
    if "rule" in params and params["rule"] not in _RULES:
        raise ValueError(f"rule: expected one of {', '.join(_RULES)}, got {params['rule']!r}")
    if "budgets" in params:
        params["budgets"] = [float(b) for b in params["budgets"]]
    text, markdown = _analyze(
        _arrow(table),
        json.dumps(params),
        taxonomy=taxonomy,
        allow_incomplete=allow_incomplete,
        name=name,
    )
    return Envelope(json.loads(text), markdown, text)


def write_synthetic_csv(path, clips=1996, seed=0):
    """Write the synthetic pairs table (the paper's scenario mix, eight conditions per clip)."""
    _synthetic_csv(str(path), int(clips), seed=int(seed))


class Envelope:
    """The analysis result: the CLI's ``envelope.json`` as :attr:`data` and tables.

    Attributes:
        data: the ``envelope.json`` object (dicts and lists).
        markdown: the CLI's ``envelope.md`` text.
    """

    def __init__(self, data, markdown, text):
        self.data = data
        self.markdown = markdown
        self._text = text

    def to_json(self):
        """The ``envelope.json`` text, as the CLI writes it."""
        return self._text

    def tables(self):
        """Names of the sections that are tables (lists of records): ``thresholds``, ``odd``, ..."""
        return [k for k, v in self.data.items() if isinstance(v, list) and v and isinstance(v[0], dict)]

    def frame(self, section, library=None):
        """A section as a DataFrame: pandas (default when installed) or ``library="polars"``.

        Without pandas or polars, the list of records.
        """
        records = self.data[section]
        if not isinstance(records, list):
            raise ValueError(f"{section} is not a table; tables: {', '.join(self.tables())}")
        if library in (None, "pandas"):
            try:
                import pandas

                return pandas.DataFrame.from_records(records)
            except ImportError:
                if library == "pandas":
                    raise
        if library in (None, "polars"):
            try:
                import polars

                return polars.DataFrame(records)
            except ImportError:
                if library == "polars":
                    raise
        if library not in (None, "pandas", "polars"):
            raise ValueError(f'library: expected "pandas" or "polars", got {library!r}')
        return records

    @property
    def thresholds(self):
        """Thresholds per scenario (and aggregate), axis and budget, as a DataFrame."""
        return self.frame("thresholds")

    @property
    def odd(self):
        """The two-dimensional ODD entries per scenario, as a DataFrame."""
        return self.frame("odd")

    def __repr__(self):
        c = self.data.get("corpus", {})
        return f"Envelope({c.get('n_pairs', '?')} pairs, {c.get('n_clips', '?')} clips)"
