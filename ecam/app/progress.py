"""The progress display of the command line: one line on stderr, only on a terminal."""

import sys


def progress_bar(label):
    """A one-line progress bar on stderr (only when it is a terminal)."""
    if not sys.stderr.isatty():
        return None

    def show(done, total):
        width = 30
        filled = int(width * done / max(total, 1))
        sys.stderr.write(f"\r{label} [{'#' * filled}{'.' * (width - filled)}] {100 * done // max(total, 1):3d}%")
        if done >= total:
            sys.stderr.write("\r" + " " * (len(label) + width + 8) + "\r")
        sys.stderr.flush()

    return show
