"""GYM modules: one per task.  ``walkman-module NAME`` runs ``walkman.modules.NAME.Module``."""
