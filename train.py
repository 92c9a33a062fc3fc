"""Train an experiment: ``python train.py experiment=exp4 [overrides]``."""
import hydra
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
    from neuroimagery.app.run import train

    info = train(cfg, checked=checked)
    console.info(f"trained {info['experiment']} ({info['participants']} {info['unit']}) in {info['runtime_s']['train']:.1f} s; "
                 f"checkpoints in {info['checkpoints']}")


if __name__ == "__main__":
    main()
