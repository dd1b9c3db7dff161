"""sphri: design robot tactile skins from interaction data.

The published API of sphri's core (the chain, its config, the stage table, the typed contracts, the
component protocols, the stage cache and the expected errors), documented in docs/reference/api.md::

    from sphri import compose, make_pipeline, open_cache

    cfg = compose(["+debug=fast"])
    windows = make_pipeline(cfg, open_cache(cfg)).get("filter")

Every name is exported lazily (:mod:`sphri._lazy`): ``import sphri`` imports no module of sphri and no
library beyond the standard library; a name's module is imported when the name is first used. The apps
beside the core (the commands, the report, the scenario study, hardware, export, recordings) import
from the core only these names; ``tests/test_api.py`` holds the fence and its written exceptions.
"""

from typing import TYPE_CHECKING

from sphri._lazy import lazy_exports

__version__ = "0.1.0"

# name -> the module that defines it; read as a dict literal by tests/test_architecture.py (module_graph)
__getattr__, __all__ = lazy_exports(
    "sphri",
    {
        # the chain
        "make_pipeline": "sphri.pipeline",
        "run": "sphri.pipeline",
        "RunResult": "sphri.pipeline",
        "Pipeline": "sphri.pipeline",
        "Memo": "sphri.pipeline",
        "open_cache": "sphri.pipeline",
        "model_factory": "sphri.pipeline",
        "config_hash": "sphri.pipeline",
        # config: composing, checking, building, and the schemas a component declares its settings in
        "compose": "sphri.config",
        "validate": "sphri.config",
        "build": "sphri.config",
        "Schema": "sphri.config",
        "ComponentSchema": "sphri.config",
        "setting": "sphri.config",
        "store": "sphri.config",
        "require": "sphri.config",
        "require_range": "sphri.config",
        "require_choice": "sphri.config",
        "Configured": "sphri.config",
        # services the core offers its apps: where the built-in configs are, output paths checked before any
        # computing, the resolution a config asks for, MLflow runs of an analysis
        "CONF_DIR": "sphri.config",
        "check_output_dir": "sphri.config",
        "check_output_file": "sphri.config",
        "check_out_apart": "sphri.config",
        "layout_res": "sphri.layout.schema",
        "default_uri": "sphri.tracking.mlflow_tracker",
        "flatten_params": "sphri.tracking.mlflow_tracker",
        "log_analysis_run": "sphri.tracking.mlflow_tracker",
        "no_artifact_bars": "sphri.tracking.mlflow_tracker",
        # the stage table
        "STAGES": "sphri.stages",
        "COMPONENTS": "sphri.stages",
        "Stage": "sphri.stages",
        "Component": "sphri.stages",
        # the typed contracts the stages exchange
        "GESTURES": "sphri.types",
        "HandModel": "sphri.types",
        "GestureDataset": "sphri.types",
        "Link": "sphri.types",
        "Robot": "sphri.types",
        "Contacts": "sphri.types",
        "SurfaceMap": "sphri.types",
        "Layout": "sphri.types",
        "Frames": "sphri.types",
        "SkinFrames": "sphri.types",
        "WindowPlan": "sphri.types",
        "TaxelGeometry": "sphri.types",
        "WindowedFrames": "sphri.types",
        "FoldResult": "sphri.types",
        "CVResult": "sphri.types",
        "FoldRecord": "sphri.types",
        "RunMeta": "sphri.types",
        # the component protocols written as classes (the others are the methods of COMPONENTS)
        "NoiseModel": "sphri.noise.components",
        "Chart": "sphri.surface.charts",
        "chart_of": "sphri.surface.charts",
        "register_chart": "sphri.surface.charts",
        "FoldStore": "sphri.evaluate.cv",
        # the stage cache
        "StageCache": "sphri.cache",
        # the expected errors the core raises (sphri.errors.EXPECTED: one line, no traceback)
        "ConfigError": "sphri.config",
        "UnknownRegion": "sphri.types",
        "DatasetError": "sphri.data.vr_gesture",
        "ManifestError": "sphri.data.format",
        "CVError": "sphri.evaluate.cv",
        "WindowMemoryError": "sphri.window.onset",
        "ContactMemoryError": "sphri.contact.stage",
        "HandDefinitionError": "sphri.hand.capsules",
        "MeshError": "sphri.robots.validate",
        "RobotFileError": "sphri.robots.urdf_tree",
        "LayoutFileError": "sphri.layout.common",
        "CorruptEntry": "sphri.cache",
        "StoreError": "sphri.tracking.store",
        "NonFiniteError": "sphri.finite",
    },
)

if TYPE_CHECKING:  # the same names for type checkers (tests/test_api.py checks that both lists agree)
    from sphri.cache import CorruptEntry as CorruptEntry
    from sphri.cache import StageCache as StageCache
    from sphri.config import CONF_DIR as CONF_DIR
    from sphri.config import ComponentSchema as ComponentSchema
    from sphri.config import ConfigError as ConfigError
    from sphri.config import Configured as Configured
    from sphri.config import Schema as Schema
    from sphri.config import build as build
    from sphri.config import check_out_apart as check_out_apart
    from sphri.config import check_output_dir as check_output_dir
    from sphri.config import check_output_file as check_output_file
    from sphri.config import compose as compose
    from sphri.config import require as require
    from sphri.config import require_choice as require_choice
    from sphri.config import require_range as require_range
    from sphri.config import setting as setting
    from sphri.config import store as store
    from sphri.config import validate as validate
    from sphri.contact.stage import ContactMemoryError as ContactMemoryError
    from sphri.data.format import ManifestError as ManifestError
    from sphri.data.vr_gesture import DatasetError as DatasetError
    from sphri.evaluate.cv import CVError as CVError
    from sphri.evaluate.cv import FoldStore as FoldStore
    from sphri.finite import NonFiniteError as NonFiniteError
    from sphri.hand.capsules import HandDefinitionError as HandDefinitionError
    from sphri.layout.common import LayoutFileError as LayoutFileError
    from sphri.layout.schema import layout_res as layout_res
    from sphri.noise.components import NoiseModel as NoiseModel
    from sphri.pipeline import Memo as Memo
    from sphri.pipeline import Pipeline as Pipeline
    from sphri.pipeline import RunResult as RunResult
    from sphri.pipeline import config_hash as config_hash
    from sphri.pipeline import make_pipeline as make_pipeline
    from sphri.pipeline import model_factory as model_factory
    from sphri.pipeline import open_cache as open_cache
    from sphri.pipeline import run as run
    from sphri.robots.urdf_tree import RobotFileError as RobotFileError
    from sphri.robots.validate import MeshError as MeshError
    from sphri.stages import COMPONENTS as COMPONENTS
    from sphri.stages import STAGES as STAGES
    from sphri.stages import Component as Component
    from sphri.stages import Stage as Stage
    from sphri.surface.charts import Chart as Chart
    from sphri.surface.charts import chart_of as chart_of
    from sphri.surface.charts import register_chart as register_chart
    from sphri.tracking.mlflow_tracker import default_uri as default_uri
    from sphri.tracking.mlflow_tracker import flatten_params as flatten_params
    from sphri.tracking.mlflow_tracker import log_analysis_run as log_analysis_run
    from sphri.tracking.mlflow_tracker import no_artifact_bars as no_artifact_bars
    from sphri.tracking.store import StoreError as StoreError
    from sphri.types import GESTURES as GESTURES
    from sphri.types import Contacts as Contacts
    from sphri.types import CVResult as CVResult
    from sphri.types import FoldRecord as FoldRecord
    from sphri.types import FoldResult as FoldResult
    from sphri.types import Frames as Frames
    from sphri.types import GestureDataset as GestureDataset
    from sphri.types import HandModel as HandModel
    from sphri.types import Layout as Layout
    from sphri.types import Link as Link
    from sphri.types import Robot as Robot
    from sphri.types import RunMeta as RunMeta
    from sphri.types import SkinFrames as SkinFrames
    from sphri.types import SurfaceMap as SurfaceMap
    from sphri.types import TaxelGeometry as TaxelGeometry
    from sphri.types import UnknownRegion as UnknownRegion
    from sphri.types import WindowedFrames as WindowedFrames
    from sphri.types import WindowPlan as WindowPlan
    from sphri.window.onset import WindowMemoryError as WindowMemoryError
