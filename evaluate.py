"""Test an experiment: ``python evaluate.py experiment=exp4 [checkpoint=DIR] [overrides]``."""
import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from neuroimagery.core import console
from neuroimagery.app.cli import friendly_errors, plain_hydra_errors
from neuroimagery.config import register_configs
from neuroimagery.validation import prepare

register_configs()
plain_hydra_errors()


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
@friendly_errors
def main(cfg: DictConfig) -> None:
    checked = prepare(cfg)  # a refused setting is answered before torch and the protocol are imported
    from neuroimagery.app.run import evaluate

    evaluate(cfg, checked=checked)
    out = HydraConfig.get().runtime.output_dir
    console.info(f"report: {out}/report.md")


if __name__ == "__main__":
    main()
