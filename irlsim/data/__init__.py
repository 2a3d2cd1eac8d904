"""Datasets on disk (Parquet): demonstrations, schema, writer, reader, summary
(docs/design/demonstrations.md and docs/design/data.md).

Public API: ``policy_distance``, ``DemoProjector`` (demos); ``EpisodeWriter``, ``episode_done``,
``write_manifest`` (writer); ``open_dataset``, ``Dataset``, ``SplitTensors`` (reader);
``dataset_info``, ``format_info`` (info); ``SCHEMA_VERSION`` (schema).
"""

from irlsim.data.demos import ALPHA, MAX_DEMO_DISTANCE, W_YAW, DemoProjector, Projection, policy_distance
from irlsim.data.info import dataset_info, format_info
from irlsim.data.layout import episode_done, remove_partial, write_manifest
from irlsim.data.reader import Dataset, SplitTensors, open_dataset
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.data.writer import EpisodeWriter

__all__ = [
    "ALPHA",
    "MAX_DEMO_DISTANCE",
    "SCHEMA_VERSION",
    "W_YAW",
    "Dataset",
    "DemoProjector",
    "EpisodeWriter",
    "Projection",
    "SplitTensors",
    "dataset_info",
    "episode_done",
    "format_info",
    "open_dataset",
    "policy_distance",
    "remove_partial",
    "write_manifest",
]
