"""CSV files of experiment rows (dicts): written atomically, read back with their types."""
import csv
import os


def write_csv(path, rows, columns=None, float_format=".6g"):
    """Rows into path (via a temporary file, so a reader never sees half a table). columns: the
    columns in order (default: the first row's keys; other keys are left out); floats formatted with
    float_format (None: as Python writes them)."""
    columns = list(columns or rows[0].keys())
    tmp = f"{path}.part"
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (format(v, float_format) if float_format and isinstance(v, float) else v)
                        for k, v in r.items()})
    os.replace(tmp, path)
    return path


def read_csv(path, types=None):
    """Rows of a CSV file as dicts; types {column: callable} converts those columns (an empty field
    becomes None); the other columns stay strings."""
    types = types or {}
    rows = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            for k, typ in types.items():
                if k in r:
                    r[k] = None if r[k] in ("", None) else typ(r[k])
            rows.append(r)
    return rows
