"""Evaluation in layers: `tax3d eval` (tax3d.cli.eval) plans the jobs, runs them, summarises and writes.

    jobs.py      EvalJob, the split folders and plan_jobs: one job an episode, from the command's arguments
    runner.py    one episode in a worker (predict, execute, judge) and run_jobs over workers
    summary.py   summarise (per split: success, RMSE, coverage, precision) and format_table
    outputs.py   results.json, summary.json and the report of an evaluation
    report.py    the HTML report, its pictures and its markdown table
    episodes.py  the finished episodes of an interrupted evaluation, kept for a rerun
    ledger.py    the ledger of test scorings
"""
