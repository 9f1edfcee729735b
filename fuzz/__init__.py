"""Coverage-guided fuzzing of every decoder: targets, a runner, found crashers (see README.md)."""
