"""FMU sources (C) and the builder: ``fmu_src.build.build_fmu`` packs a model's variable list
(``fmu_src.variables``) and C code (``fmu_src/common``, ``fmu_src/<model>``) into FMI 2.0 or
3.0 co-simulation FMUs."""
