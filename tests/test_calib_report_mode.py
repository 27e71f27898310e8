"""calib's reports and parameter files are written atomically, with the mode a plain open() gives
(issue 29, item 10: demo-out/calibration.md was created 0600 by mkstemp)."""
from __future__ import annotations

import os
import stat

from rcci.calib.params import atomic_write


def test_a_new_report_gets_the_umask_mode_not_mkstemps_0600(tmp_path):
    old = os.umask(0o022)
    try:
        atomic_write(str(tmp_path / "calibration.md"), "# report\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "calibration.md").st_mode) == 0o644
    assert (tmp_path / "calibration.md").read_text() == "# report\n"
    assert [p.name for p in tmp_path.iterdir()] == ["calibration.md"]       # no temporary file left


def test_a_replaced_file_keeps_its_mode(tmp_path):
    path = tmp_path / "params.toml"
    path.write_text("old")
    os.chmod(path, 0o640)
    atomic_write(str(path), "new")
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o640 and path.read_text() == "new"
