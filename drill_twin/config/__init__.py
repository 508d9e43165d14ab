"""Configuration: YAML files -> validated, frozen dataclasses (see ``schema``)."""
from drill_twin.config.loader import ConfigError, build_config, config_to_dict, load_config
from drill_twin.config.schema import DrillStringConfig

__all__ = ['ConfigError', 'DrillStringConfig', 'build_config', 'config_to_dict', 'load_config']
