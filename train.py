"""Train an experiment: ``python train.py experiment=exp4 [overrides]``."""
import hydra
from omegaconf import DictConfig

from neuroimagery.core import console
from neuroimagery.app.cli import friendly_errors, plain_hydra_errors
from neuroimagery.config import register_configs
from neuroimagery.app.run import train

register_configs()
plain_hydra_errors()


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
@friendly_errors
def main(cfg: DictConfig) -> None:
    info = train(cfg)
    console.info(f"trained {info['experiment']} ({info['participants']} {info['unit']}) in {info['runtime_s']['train']:.1f} s; "
                 f"checkpoints in {info['checkpoints']}")


if __name__ == "__main__":
    main()
