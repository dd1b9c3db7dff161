"""Every config range physical (issue 29, item 3): more folds than a participant has windows is refused."""

from __future__ import annotations

import pytest
from test_cv import spy_windows

from sphri.evaluate.cv import CVError, WithinSubjectKFold


def test_more_folds_than_a_participants_windows_is_refused_naming_both_numbers():
    """Reproducer (issue 29): ``cv.k=1000`` silently became 46 one-trial folds."""
    win = spy_windows(participants=3, per_class=2)  # 16 windows per participant
    with pytest.raises(
        CVError,
        match=r"cv\.k=1000 is more than the 16 windows of participant_0\d \(the participant "
        r"with the fewest of 3\).*set cv\.k<=16",
    ):
        WithinSubjectKFold(k=1000).splits(win)
    with pytest.raises(CVError, match=r"cv\.k=17 is more than the 16 windows"):
        WithinSubjectKFold(k=17).splits(win)
    folds = WithinSubjectKFold(k=16).splits(win)  # at the limit: every fold tests every participant once
    assert len(folds) == 16
    assert all(len(set(win.groups[f.test])) == 3 for f in folds)
