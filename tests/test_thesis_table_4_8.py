"""Table 4.8 as the calibration report compares with it: row j3A's value is the thesis's -2.938
(the OCR text reads -1.938), which its own result and Table 4.9 require (issue 29, item 11)."""
from __future__ import annotations

import pytest

from rcci.calib.fits.gravity import J3A_NOTE, THESIS_4_8

C13_J3B = -1.744            # Table 4.8, row j3B / joint 3: c13
C15_J3A_RESULT = -1.194     # Table 4.8, row j3A: its printed result c15
C13_4_9, C15_4_9 = -1.762, -1.192    # Table 4.9


def test_row_j3a_is_the_sum_its_result_needs():
    combination, value = THESIS_4_8[("j3A", 3)]
    assert combination == "c13 + c15"
    assert value == pytest.approx(C13_J3B + C15_J3A_RESULT, abs=1e-9)       # -2.938
    assert abs(value - (C13_4_9 + C15_4_9)) < 0.02                            # Table 4.9: -2.954
    assert abs(-1.938 - (C13_4_9 + C15_4_9)) > 1.0                            # the OCR's value is not


def test_the_report_says_why():
    assert "-2.938" in J3A_NOTE and "-1.938" in J3A_NOTE and "-2.954" in J3A_NOTE
