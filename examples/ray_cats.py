"""CATS augmentation of a dataset with Ray tasks: N tasks, task I writes shard I/N with the
Python API (`laparo.cats.augment_dataset`, the files of `laparo cats augment`); together they
write exactly the files of one run.

    pip install ray
    python examples/ray_cats.py INPUT OUT --layout sceneflow --shards 8 [--config cats.toml]

The same pattern works with Dask (`dask.delayed`) or concurrent.futures.
"""
import argparse

import ray

import laparo


@ray.remote
def augment_shard(input_root, layout, out, config_path, seed, shard):
    laparo.set_num_threads(1)  # one core per Ray task
    cfg = laparo.cats.CatsConfig.from_file(config_path) if config_path else None
    return laparo.cats.augment_dataset(input_root, layout, out, cfg, seed=seed, shard=shard)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("input")
    ap.add_argument("out")
    ap.add_argument("--layout", default="sceneflow")
    ap.add_argument("--config")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shards", type=int, default=8)
    a = ap.parse_args()
    ray.init()
    jobs = [augment_shard.remote(a.input, a.layout, a.out, a.config, a.seed, f"{i}/{a.shards}") for i in range(a.shards)]
    print(f"augmented {sum(ray.get(jobs))} samples into {a.out}")


if __name__ == "__main__":
    main()
