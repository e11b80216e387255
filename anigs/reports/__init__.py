"""Reports over finished runs: the paper's tables from the metric records (:mod:`~anigs.reports.tables`,
formatted by :mod:`~anigs.reports.table_format`), the accuracy-versus-time sweep
(:mod:`~anigs.reports.tradeoff`) and the Snakemake benchmark files per rule
(:mod:`~anigs.reports.benchmark_tsv`)."""
