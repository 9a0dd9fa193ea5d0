"""What runs produce, between the master and the commands.

- :mod:`.summary`: the metrics of one iteration (``summary.csv``'s columns) from its trace;
- :mod:`.pulses`: the pulses of a trace and the bound no pulse may exceed (no runaway);
- :mod:`.folder`: the output folder of ``papwc run``, written as results come;
- :mod:`.plots`: plots of runs (PNG);
- :mod:`.cosim_stream`: the rows of an SSP run streamed to CSV, and its plot (``papwc cosim``).

Files are written through :mod:`papwc.output_files` (whole or not at all).
"""
