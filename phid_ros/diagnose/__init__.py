"""Missing-physics workflow: where model and measurement disagree, and which effect explains it."""
