"""Building the project's FMUs and SSP (what ``papwc build`` writes).

- :mod:`.fmus`: which FMUs there are and what each is built from;
- :mod:`.native_build`: the native (C) FMUs, compiled by zig for win64, linux64 and
  darwin64 (FrictionPlant, the default), with :mod:`.native_tables` (its generated header);
- :mod:`.pythonfmu_build`: the one recipe every FMU goes through (pythonfmu,
  model description from the model layer, reproducible archive, validation);
- :mod:`.model_description`: completing a model description from the metadata;
- :mod:`.ssp_writer`: ``ClosedLoop.ssp``;
- :mod:`.reference`: FrictionPlant's reference result (FMI cross-check layout).
"""
