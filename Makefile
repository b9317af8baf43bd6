# morphoshell: `make run` and `make test` do all the set-up on a fresh machine.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test docs fuzz bench figures campaign clean

# test, docs, xarray and dask extras: make test also builds the docs, checks to_xarray() and runs a 2-worker Dask LocalCluster
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,docs,xarray,dask]'
	touch $(STAMP)

## run: solve every problem in problems/ (plots, JSON, out/summary.json), draw Fig. 2 D-I and
## Fig. 2 J-K (estimates from the synthetic ablation table data/synthetic_ablations.csv), and a
## short fit campaign (3 synthetic timepoints x 3 variants, gradient, 100 nodes: about a minute)
run: $(STAMP)
	$(BIN)/python scripts/main_job.py --out out
	$(BIN)/python scripts/fig2_toy_problems.py --out out/figures
	$(BIN)/python scripts/fig2jk_estimates.py --out out/figures
	$(BIN)/morphoshell campaign data/synthetic_inversion --timepoints t01,t02,t03 --variants flat,unstressed,free --method gradient --nodes 100 --workers 2 --out out/campaign_short

## campaign: the full fit campaign on the synthetic inversion sequence (12 timepoints x 4
## variants, gradient method; jackknife errors for the free fit) into out/campaign, the tests
## of the held values (the fixed variants with f1, kappa3, kappa4 of the flat first fit, SI
## Fig. S2, and of the free first fit, which assumes no hypothesis) into
## out/campaign_held_flat and out/campaign_held_free, then Fig. 3 D-O and Fig. S2 into out/figures
## (--allow-failures: a late stage's fit that does not converge, documented in docs/campaigns.md,
## is shown in the figures as such, not a reason to stop before them)
campaign: $(STAMP)
	mkdir -p out  # (campaign --out creates its folder only inside an existing one)
	$(BIN)/morphoshell campaign data/synthetic_inversion --method gradient --embryo-errors free --allow-failures --out out/campaign
	$(BIN)/morphoshell campaign data/synthetic_inversion --method gradient --variants flat,undeformed,unstressed --held-from flat --allow-failures --out out/campaign_held_flat
	$(BIN)/morphoshell campaign data/synthetic_inversion --method gradient --variants flat,undeformed,unstressed --held-from free --allow-failures --out out/campaign_held_free
	$(BIN)/python scripts/fig3_fits.py --campaign out/campaign --held out/campaign_held_flat --held out/campaign_held_free --out out/figures

## test: the whole test suite (with a strict build of the docs, tests/test_docs.py, and a
## clean-venv install of the package and a plugin, tests/test_packaging.py), on two pytest-xdist
## workers: the solvers are single-threaded, so two cores halve the time
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2

## docs: the documentation and its API reference into site/ (any warning is an error)
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

## fuzz: property-based fuzzing, 1500 random problems, 187 branches and 3000 bad command
## lines; prints the counts (maintainers, before a release: about 6 minutes on 2 cores at
## load 1, more with the branches; docs/benchmarks.md)
fuzz: $(STAMP)
	MORPHOSHELL_FUZZ=fuzz $(BIN)/python -m pytest -q -s -p no:cacheprovider tests/test_fuzz.py

## bench: timing tables (scripts/bench_*.py)
bench: $(STAMP)
	$(BIN)/python scripts/bench_equilibrium.py --large
	$(BIN)/python scripts/bench_inverse.py

clean:
	rm -rf out site .pytest_cache build src/*.egg-info
