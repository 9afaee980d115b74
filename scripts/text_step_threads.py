"""Time a text-transformer training step (own inputs 0.5, forward, backward, AdamW) on 300 v1
training objects, for a thread count and batch size: would two 1-thread data-parallel workers
beat one 2-thread process? Needs data/prepared/v1 and a targets cache of it (CACHE, default
runs/s23/text_xyz/cache; any `artformer train transformer --out` folder's cache).
Usage: python scripts/text_step_threads.py THREADS BATCH [CACHE]"""
import sys, time
import numpy as np, torch
from dataclasses import asdict
from model.articulation.config import preset
from model.articulation.commands import make_targets
from model.articulation import train as T
from model.articulation.data import TextCache, group_rounds
from model.articulation.network import ArticulationTransformer
threads, bs_ = int(sys.argv[1]), int(sys.argv[2])
torch.set_num_threads(threads)
cfg, tc = preset("small")
tg = make_targets("model/weights/prior_small.pt", "model/weights/sdf_small.pt", cfg)
cfg.cs_dim = int(tg.cs_dim); cfg.num_codebooks, cfg.codebook_size = int(tg.num_codebooks), int(tg.codebook_size)
view = T._CodebookView(tg, cfg)
data = T.prepare_data("data/prepared/v1", view, cache_dir=sys.argv[3] if len(sys.argv) > 3 else "runs/s23/text_xyz/cache", progress=False)
tr = data.items["train"][:300]
tcache = TextCache(tc.text_encoder)
tcache.add([t for it in tr for g in it.texts for t in g])
cfg.count_labels = sorted(set(data.label_table["labels"]))
label_cs = T.label_cs_normalised(data)
rng = np.random.default_rng(0)
bs = []
while len(bs) < 50:
    ep = group_rounds(tr, rng.permutation(len(tr)), bs_, tc.rounds_per_object, rng)
    bs += [(g, T.make_batch(tr, g, data.geo_shape, tcache, rng, label_cs, cfg.count_labels)) for g in ep[:50 - len(bs)]]
torch.manual_seed(0)
net = ArticulationTransformer(cfg)
opt = torch.optim.AdamW(net.parameters(), lr=1e-4, weight_decay=0.01, betas=(0.9, 0.98))
net.train()
r2 = np.random.default_rng(1)
def step(gb):
    groups, (batch, targets, cond, cmask, idx) = gb
    T.own_input_tokens(net, tr, groups, batch, cond, cmask, "text", 0.5, r2, data.geo_shape)
    _, L = net(batch, cond, cmask, "text", cond_index=idx, targets=targets, weights=asdict(tc))
    opt.zero_grad(set_to_none=True)
    L["total"].backward()
    opt.step()
for gb in bs[:10]: step(gb)
t = time.time()
for gb in bs[10:]: step(gb)
dt = (time.time() - t) / 40
print(f"threads {threads} batch {bs_}: {dt*1000:.0f} ms/step, {bs_/dt:.0f} rounds/s")
