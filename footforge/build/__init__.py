"""`footforge build` and `footforge check`: descriptions in, checked MJCF and USD models out.

pipeline: the build (BuildOptions -> build_report.json and the model files); report: the
figures of a compiled model the report holds; check: a description's defects, without building."""

from footforge.build.pipeline import FORMATS, VARIANTS, BuildOptions, build

__all__ = ["FORMATS", "VARIANTS", "BuildOptions", "build"]
