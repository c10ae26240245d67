"""Running a case: the time loop, its guards, the ledger, checkpoints, progress."""
