"""The colours every figure of the rig shares (GitHub's Primer palette: red for a limit or a
failure, green for a pass, a light grey grid), so a limit looks the same in every panel."""

LIMIT = "#cf222e"
PASSED = "#1a7f37"
GRID = "#d0d7de"
