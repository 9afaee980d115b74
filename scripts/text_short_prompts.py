"""Short user-style prompts built from held-out objects, naming only the moving part kinds
("a cabinet with four drawers and two doors", no handles): how many the text model aligns
with the product decoding (T = 0.3 + plan). Usage: python scripts/text_short_prompts.py DATA SPLIT CKPT"""
import sys, torch
from collections import Counter
from model.articulation.decode import ArticulationModel
from model.articulation.evaluate import _prompt_checker
from model.data import format as fmt
from model.data.vocab import CATEGORY_SYNONYMS, number_word, plural
torch.set_num_threads(2)
root, split, ck = sys.argv[1], sys.argv[2], sys.argv[3]
check = _prompt_checker()
am = ArticulationModel.load(ck)
m = fmt.load_manifest(root)
prompts = []
for i in m["splits"][split]:
    r = fmt.load_record(root, i)
    c = Counter(l for l in r.labels if l not in ("body", "handle"))
    if not c:
        continue
    parts = [f"a {lab}" if n == 1 else f"{number_word(n)} {plural(lab)}" for lab, n in sorted(c.items())]
    prompts.append(f"a {CATEGORY_SYNONYMS[r.category][0]} with " + " and ".join(parts))
ok = 0
bad = []
for s in range(0, len(prompts), 32):
    chunk = prompts[s:s + 32]
    tok, mask = am.encode_text(chunk)
    trees = am.decode(tok, mask, seed=s, temperature=0.3, follow_plan=True)
    for p, t in zip(chunk, trees):
        r = check(p, t)
        if r.checked:
            ok += r.aligned
            if not r.aligned:
                bad.append((p, dict(Counter(t.labels))))
print(f"{ok}/{len(prompts)} aligned")
for b in bad[:40]:
    print("  ", b)
