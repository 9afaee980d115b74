"""Decode each prompt of a file (one per line, '#' comments) with 8 seeds at the product's
structure decoding and count the aligned trees (model.metrics alignment), with the structures
made. Usage: python scripts/text_prompt_seeds.py PROMPTS [TEMPERATURE [CKPT]]"""
import sys, torch
from model.articulation.decode import ArticulationModel
from model.articulation.evaluate import _prompt_checker
from model.metrics.prompt_parse import parse_prompt
torch.set_num_threads(2)
check = _prompt_checker()
prompts = [l.strip() for l in open(sys.argv[1]) if l.strip() and not l.startswith("#")]
ck = sys.argv[3] if len(sys.argv) > 3 else "model/weights/transformer_small.pt"
am = ArticulationModel.load(ck)
T = float(sys.argv[2]) if len(sys.argv) > 2 else 0.3
n = 8
tot = 0
for p in prompts:
    tok, mask = am.encode_text([p])
    ok = []
    seen = {}
    for s in range(n):
        tr = am.decode(tok, mask, seed=s, temperature=T, follow_plan=True)[0]
        r = check(p, tr)
        ok.append(r.aligned)
        c = tr.summary()["counts"]
        key = ",".join(f"{k}{v}" for k, v in sorted(c.items()))
        seen[key] = seen.get(key, 0) + 1
    tot += sum(ok)
    print(f"{sum(ok)}/{n}  {p!r}  parsed={parse_prompt(p)}\n      {seen}")
print("total", tot, "/", n * len(prompts))
