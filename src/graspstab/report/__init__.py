"""The self-contained HTML report (thesis chapter 4); grows with each stage of the pipeline."""
