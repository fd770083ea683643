"""What rank 0 knows of the compressions that trial tasks use, and what a
trial task is sent: the forces `F_tot` (nN, shape tensions × heights, NaN
where a compression is not done) and, per tension, the message of its first
compression that is not done. Workers never read the store."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from campaign.store import DONE, FAILED, PENDING, STATES

if TYPE_CHECKING:
    from campaign.config import Campaign
    from campaign.store import Store


class TrialInputs:
    """The forces, states and errors of every compression, kept current by
    `compression_finished`, and which trial tasks are to do."""

    def __init__(self, store: Store, campaign: Campaign, retry_failed: bool):
        self.studies = campaign.studies
        state = store.trial_state()
        redo = (state == PENDING) | ((state == FAILED) if retry_failed else False)
        self.todo = [j for j in range(len(self.studies)) if redo[j].any()]
        self.done0 = int(np.sum((state == DONE).all(axis=1))) if len(self.studies) else 0
        self.attempts = store.trial_attempts()
        self.force: np.ndarray
        self.state: np.ndarray
        self.force, self.state, self.error = store.compressions() if self.studies else (np.zeros(0), np.zeros(0), [])

    def waits(self) -> dict[int, list[int]]:
        """Per trial task to do: the compressions (grid indices) it uses."""
        return {j: self.studies[j].dependencies() for j in self.todo}

    def compression_finished(self, row: int, state: str, results: dict[str, Any], error: str) -> None:
        """Note a compression's result."""
        if self.studies:
            self.state[row] = STATES.index(state)
            self.force[row] = results.get("force_nN", float("nan"))
            self.error[row] = error

    def payload(self, j: int) -> tuple[np.ndarray, list[str]]:
        """(forces, errors) for trial task j (module docstring)."""
        study = self.studies[j]
        rows = np.array(study.rows)
        done = self.state[rows] == DONE
        forces = np.where(done, self.force[rows], np.nan)
        errors = []
        for i, line in enumerate(rows):
            bad = [r for r in line if self.state[r] != DONE]
            errors.append("" if not bad else
                          f"compression {bad[0]} (h0 = {study.heights_um[list(line).index(bad[0])]:g} um, "
                          f"gamma_a = {study.tensions_mN_per_m[i]:g} mN/m) failed: {self.error[bad[0]]}")
        return forces, errors
