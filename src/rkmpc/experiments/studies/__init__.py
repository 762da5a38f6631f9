"""Studies over many independent runs: every track (:mod:`.tracks`), and data volume (:mod:`.data`)."""
