"""What a run shows (no ROS): metrics per state table and as time series (`metrics`), the paper's
behaviours as checks (`outcomes`), figures like the paper's (`plots`), and a run's analysis
and output files (`outputs`)."""
from swarm_core.analysis.outputs import analyse, summary_of, write_outputs

__all__ = ['analyse', 'summary_of', 'write_outputs']
