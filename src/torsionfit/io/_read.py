"""Reading one run file (CSV or CSV.gz) into a table of text cells, and selecting rows.

Cells stay text until a column is asked for as numbers: columns the campaign does not use
may hold anything (bench exports carry status words, empty columns, ...), and a bad value in
a used column is reported with the line it sits on.
"""

import csv
import gzip
import itertools
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._errors import InputError

#: delimiters tried on the header line, most common first
_DELIMITERS = (",", ";", "\t")


@dataclass(frozen=True, eq=False)
class Table:
    """Data rows of one CSV file. ``cells[name]`` holds the column as text; ``lines`` the
    1-based line number of each row in the file (comments and header count), for messages."""

    where: str  # message prefix naming the manifest, the run and the file
    header: tuple[str, ...]
    cells: dict[str, np.ndarray]
    lines: np.ndarray
    duplicated: tuple[str, ...] = ()  # header names that occur more than once

    def __len__(self) -> int:
        return len(self.lines)

    def column_list(self) -> str:
        return ", ".join(self.header)

    def require(self, name: str, role: str = "") -> None:
        """InputError unless column ``name`` exists once; ``role`` says why it was wanted."""
        if name in self.duplicated:
            raise InputError(f"{self.where}: column {name!r} appears more than once in the header")
        if name not in self.cells:
            why = f" ({role})" if role else ""
            raise InputError(
                f"{self.where}: column {name!r}{why} not found; columns are {self.column_list()}"
            )

    def numbers(self, name: str, finite: bool = True) -> np.ndarray:
        """Column ``name`` as finite floats; InputError naming the line of the first bad cell.
        With ``finite=False`` NaN, inf and empty cells read as NaN (for [runs.select], which
        drops them) and only text that is no number at all is an error."""
        self.require(name)
        text = self.cells[name]
        if not finite:
            text = np.where(np.char.strip(text) == "", "nan", text)
        try:
            values = text.astype(float)
        except ValueError:
            # Slow path only to find the culprit: numpy does not say which cell failed.
            for i, cell in enumerate(text):
                try:
                    float(cell)
                except ValueError:
                    shown = repr(str(cell)) if cell.strip() else "an empty cell"
                    raise InputError(
                        f"{self.where}: column {name!r} line {self.lines[i]}: "
                        f"expected a number, got {shown}{_comma_hint(cell)}"
                    ) from None
            raise  # pragma: no cover - astype and float() agree
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size and finite:
            i = bad[0]
            raise InputError(
                f"{self.where}: column {name!r} line {self.lines[i]}: expected a finite number, "
                f"got {str(text[i]).strip()!r} ({bad.size} non-finite value(s) in the column)"
            )
        return values

    def subset(self, keep: np.ndarray) -> "Table":
        """The rows where boolean ``keep`` is true."""
        return Table(
            self.where,
            self.header,
            {k: v[keep] for k, v in self.cells.items()},
            self.lines[keep],
            self.duplicated,
        )


#: a number written with a decimal comma, e.g. "1,23" or "-0,5e-3"
_DECIMAL_COMMA = re.compile(r"[+-]?\d+,\d+(?:[eE][+-]?\d+)?")


def _comma_hint(text: str) -> str:
    """A hint for text that holds a decimal comma, else ''."""
    if not _DECIMAL_COMMA.search(str(text)):
        return ""
    return ("; it looks like a decimal comma: write numbers with a decimal point (1.23), "
            "or export the file with '.' as decimal separator")


def _open_text(path: Path):
    # gzip by suffix; utf-8-sig drops the byte-order mark spreadsheet exports start with.
    if path.suffix.lower() == ".gz":
        return gzip.open(path, "rt", encoding="utf-8-sig", newline="")
    return open(path, encoding="utf-8-sig", newline="")


def read_table(path: Path, where: str) -> Table:
    """Read a comma (or semicolon / tab) separated file with one header row.

    Lines starting with ``#`` are comments (synthetic files carry a label line) and blank
    lines are skipped, anywhere in the file. Every data row must have as many fields as the
    header. ``where`` starts every error message.
    """
    if not path.is_file():
        looked = "not found" if not path.exists() else "is not a file"
        raise InputError(f"{where}: run file {looked} (looked for {path})")
    line_numbers: list[int] = []

    def data_lines(handle):
        for number, line in enumerate(handle, start=1):
            stripped = line.strip()
            if not stripped or stripped.startswith("#"):
                continue
            line_numbers.append(number)
            yield line

    try:
        with _open_text(path) as handle:
            lines = data_lines(handle)
            first = next(lines, None)
            if first is None:
                raise InputError(f"{where}: file is empty; expected a header row and data rows")
            delimiter = max(_DELIMITERS, key=first.count)
            reader = csv.reader(itertools.chain([first], lines), delimiter=delimiter)
            header = tuple(name.strip() for name in next(reader))
            header_line = line_numbers[0]
            rows: list[list[str]] = []
            row_lines: list[int] = []
            for row in reader:
                if len(row) != len(header):
                    # more comma-separated fields than names: decimal commas split the numbers
                    extra = delimiter == "," and len(row) > len(header)
                    comma = _comma_hint(",".join(row)) if extra else ""
                    raise InputError(
                        f"{where}: line {line_numbers[-1]} has {len(row)} fields, "
                        f"the header (line {header_line}) has {len(header)}{comma}"
                    )
                rows.append(row)
                row_lines.append(line_numbers[-1])
    except (OSError, EOFError, UnicodeDecodeError, csv.Error) as err:
        # gzip.BadGzipFile is an OSError; truncated archives raise EOFError.
        raise InputError(f"{where}: cannot read the file as CSV text ({err})") from None

    if not rows:
        raise InputError(f"{where}: no data rows below the header (line {header_line})")
    # A name used twice is only an error if the campaign asks for that column.
    duplicated = tuple(sorted({name for name in header if header.count(name) > 1}))
    cells = {
        name: np.array(column, dtype=str)
        for name, column in zip(header, zip(*rows))
        if name not in duplicated
    }
    return Table(where, header, cells, np.asarray(row_lines, dtype=int), duplicated)


def missing_cells(text: np.ndarray) -> np.ndarray:
    """True where a cell is empty or a non-finite number (NaN, inf): a pad, not data."""
    stripped = np.char.lower(np.char.strip(text))
    return np.isin(stripped, ("", "nan", "+nan", "-nan", "inf", "+inf", "-inf", "infinity",
                              "+infinity", "-infinity", "na", "n/a", "null"))


def drop_trailing_pad(table: Table, columns: list[str]) -> tuple[Table, int]:
    """``table`` without its trailing rows in which every one of ``columns`` is missing (a
    side-by-side export pads the shorter direction), and how many rows were dropped."""
    columns = [c for c in columns if c in table.cells]  # a duplicated name fails on reading
    if not columns:
        return table, 0
    missing = np.ones(len(table), dtype=bool)
    for column in columns:
        missing &= missing_cells(table.cells[column])
    n = 0
    while n < len(table) and missing[len(table) - 1 - n]:
        n += 1
    if n == 0:
        return table, 0
    keep = np.ones(len(table), dtype=bool)
    keep[len(table) - n:] = False
    return table.subset(keep), n


def describe_rule(column: str, rule) -> str:
    """Human text of one ``[runs.select]`` / ``[runs.condition]`` rule."""
    if isinstance(rule, dict):
        parts = []
        if "min" in rule:
            parts.append(f"{column} >= {rule['min']}")
        if "max" in rule:
            parts.append(f"{column} <= {rule['max']}")
        return " and ".join(parts)
    return f"{column} in [{', '.join(str(v) for v in rule)}]"


def select_rows(table: Table, select: dict, where: str) -> Table:
    """Keep the rows that pass every rule of ``[runs.select]`` (file column → rule).

    A rule is a list of allowed values (numbers are compared as numbers, strings as the
    cell text) or a table ``{min = .., max = ..}`` (inclusive, either bound optional).
    The manifest reader has already checked the rules' types.
    """
    return table.subset(rows_passing(table, select, where, "[runs.select]"))


def rows_passing(table: Table, rules: dict, where: str, section: str) -> np.ndarray:
    """(rows,) True where a row passes every rule (file column → rule, as ``[runs.select]``'s);
    InputError when a rule, or all of them together, match no row."""
    keep = np.ones(len(table), dtype=bool)
    for column, rule in rules.items():
        table.require(column, f"from {section}")
        numeric = isinstance(rule, dict) or all(not isinstance(v, str) for v in rule)
        if numeric:
            # a NaN or empty cell fails every rule: the row is dropped, not an error
            values = table.numbers(column, finite=False)
            if isinstance(rule, dict):
                passed = np.ones(len(table), dtype=bool)
                if "min" in rule:
                    passed &= values >= rule["min"]
                if "max" in rule:
                    passed &= values <= rule["max"]
            else:
                passed = np.isin(values, np.asarray(rule, dtype=float))
        else:
            values = np.char.strip(table.cells[column])
            passed = np.isin(values, np.asarray(rule, dtype=str))
        if not passed.any():
            present = np.unique(values)
            shown = ", ".join(_short(v) for v in present[:12])
            more = f", ... ({present.size} distinct)" if present.size > 12 else ""
            raise InputError(
                f"{where}: {section} {describe_rule(column, rule)} matches no row; "
                f"the column holds {shown}{more}"
            )
        keep &= passed
    if not keep.any():
        text = "; ".join(describe_rule(c, r) for c, r in rules.items())
        raise InputError(f"{where}: {section} rules together match no row ({text})")
    return keep


def _short(value) -> str:
    if isinstance(value, (float, np.floating)):
        return f"{float(value):g}"
    return str(value)
