"""The one owner of a run folder's layout: where each file goes and how ``summary.csv`` is read.

::

    <out>/summary.csv, summary.md, report.html, report.md, claims.md
    <out>/<experiment>/<loop mode>/<controller>.csv     one time series per run

Names become path parts only through :func:`~otmm_qp.output.paths.safe_name` (controller
slugs made unique per experiment), and every path is checked to stay inside the folder.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from pathlib import Path

from otmm_qp.exceptions import ConfigError
from otmm_qp.output.paths import ensure_inside, safe_name, unique_names

SUMMARY_CSV = "summary.csv"
SUMMARY_MD = "summary.md"
REPORT_HTML = "report.html"
REPORT_MD = "report.md"
CLAIMS_MD = "claims.md"
#: Columns every ``summary.csv`` row has: which run it is.
IDENTITY_COLUMNS = ("experiment", "loop_mode", "controller")


class ResultsDir:
    """A run folder (``otmm-qp run --out``).

    Args:
        path: The folder.
    """

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)

    def file(self, name: str) -> Path:
        """A top-level file of the folder (e.g. :data:`SUMMARY_CSV`), checked to stay inside."""
        return ensure_inside(self.path, self.path / name)

    def run_csv(
        self, experiment: str, loop_mode: str, controller: str, names: Sequence[str]
    ) -> Path:
        """``<experiment>/<loop mode>/<controller>.csv`` through the safe, unique names.

        Args:
            experiment: Experiment name.
            loop_mode: Loop mode.
            controller: Controller name.
            names: Controller names of the experiment, in config order (for unique slugs).

        Raises:
            OutputPathError: The path would leave the folder.
        """
        stem = unique_names(list(names))[controller]
        folder = self.path / safe_name(experiment) / safe_name(loop_mode)
        return ensure_inside(self.path, folder / f"{stem}.csv")

    def read_text(self, path: Path) -> str:
        """A text file of the folder; refuses links out of it and non-UTF-8 bytes.

        Raises:
            OutputPathError: ``path`` is outside the folder.
            ConfigError: Not UTF-8, or unreadable.
        """
        ensure_inside(self.path, path)
        try:
            return path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ConfigError(str(path), "not UTF-8 text; is this a results folder?") from None
        except OSError as error:
            raise ConfigError(str(path), f"cannot read: {error.strerror}") from None

    def summary_records(self, required: Sequence[str] = IDENTITY_COLUMNS) -> list[dict[str, str]]:
        """The rows of ``summary.csv`` as text cells (a cell missing from a truncated file is "").

        Args:
            required: Columns the file must have.

        Raises:
            ConfigError: No ``summary.csv``, not a readable CSV, or a required column missing.
        """
        path = self.path / SUMMARY_CSV
        if not path.is_file():
            raise ConfigError(str(path), "no summary.csv here; run an experiment first")
        text = self.read_text(path)
        try:
            reader = csv.DictReader(io.StringIO(text, newline=""))
            missing = [c for c in required if c not in (reader.fieldnames or ())]
            if missing:
                raise ConfigError(str(path), f"missing columns {', '.join(missing)}")
            return [
                {str(k): (v if isinstance(v, str) else "") for k, v in record.items()}
                for record in reader
            ]
        except csv.Error as error:
            raise ConfigError(str(path), f"not a readable CSV: {str(error)[:120]}") from None
