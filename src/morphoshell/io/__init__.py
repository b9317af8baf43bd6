"""Files in and out: problem files, traced midlines, and JSON/CSV output.

Problem files (TOML) and their overrides and the writers of results
(:mod:`.problem_files`), the packaged example problems (:mod:`.example_problems`);
trace files of midlines from Fiji/ImageJ and CSV (:mod:`.traces`; their text forms,
:mod:`.trace_text`; their checks,
:mod:`.trace_checks`) and ImageJ's ROI Manager sets (:mod:`.roi_sets`), and
their geometry: noise and binning (:mod:`.trace_noise`), points equally spaced in
arclength (:mod:`.resampling`), alignment to the model gauge, resampling and averaging
(:mod:`.midlines`); the tables of ablation
measurements (:mod:`.measurements`) and of an inversion sequence's timepoints
(:mod:`.timepoints`); saved equilibria read back (:mod:`.equilibria`).  Every reader
names the file and the offending entry.
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "problem_files": ["ProblemFileError", "Settings", "load_problem", "parse_overrides",
        "apply_overrides", "split_overrides", "settings_from", "to_jsonable", "write_json",
        "write_csv", "METHODS", "SOLVER_KEYS", "ALIASES", "problem_of_record", "write_problem",
        "problem_toml"],
    "example_problems": ["examples", "example_path", "example_text", "EXAMPLES_DIR"],
    "traces": ["FORMATS", "Trace", "Midline", "read_trace", "to_image", "write_trace"],
    "trace_checks": ["MidlineError"],
    "midlines": ["SECTIONS", "Alignment", "align", "resample", "resample_spread", "load_midline",
        "load_midlines", "average", "trace_distances"],
    "measurements": ["MEASURES", "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "MEASURE_COLUMN",
        "ERROR_COLUMN", "UNITS", "MeasurementError", "Measurement", "read_measurements",
        "to_dimensionless", "to_physical"],
    "timepoints": ["Timepoint", "read_timepoints"],
    "roi_sets": ["read_roi_set", "choose_rois", "read_set_traces"],
    "equilibria": ["load_equilibrium", "equilibrium_of_record"],
})
