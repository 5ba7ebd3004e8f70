"""Parameter studies (no ROS): a grid over scenario fields × seeds, run on an engine with a
cache, as a tidy table and pass rates with confidence intervals."""
from swarm_core.study.grid import MAX_CELLS, MAX_RUNS, ROBOT_SET, Study, StudyError, parse_set, parse_values
from swarm_core.study.runner import ENGINES, code_version, load_study, make_study, run_study, run_task, tasks, validate
from swarm_core.study.tables import (
                                     plot_rates,
                                     rates,
                                     rates_csv,
                                     rates_markdown,
                                     robot_metrics_markdown,
                                     to_csv,
                                     to_parquet,
                                     wilson,
)

__all__ = ['ENGINES', 'MAX_CELLS', 'MAX_RUNS', 'ROBOT_SET', 'Study', 'StudyError', 'code_version', 'load_study',
           'make_study', 'parse_set', 'parse_values', 'plot_rates', 'rates', 'rates_csv', 'rates_markdown',
           'robot_metrics_markdown', 'run_study', 'run_task', 'tasks', 'to_csv', 'to_parquet', 'validate',
           'wilson']
