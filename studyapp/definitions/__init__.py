"""A study's definition: its recipe as one YAML file (settings, questions, systems by digest, controls
by how they are made; no participants, ratings or files), written from a study and made into a new one.
The whole study with its data is a bundle (``studyapp.bundles``).

``describe`` writes a study's settings, questions, systems and controls as YAML;
``create`` makes a study from such a file through the checks of the study's pages;
``reading`` reads the file's YAML with the line of every value, refusing hostile text;
``layout`` is the shape both follow.
"""

from studyapp.definitions.create import create_study_from_definition
from studyapp.definitions.describe import definition_yaml, describe_study
from studyapp.definitions.errors import DefinitionError

__all__ = ["DefinitionError", "create_study_from_definition", "definition_yaml", "describe_study"]
