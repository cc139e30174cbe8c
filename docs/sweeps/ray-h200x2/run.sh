ls $HOME/dw/warp >/dev/null 2>&1 || (cat $HOME/dw/part00 .devpack/part01 | tar x -C $HOME/dw && xz -dc $HOME/dw/warp.tar.xz | tar x -C $HOME/dw && python3 -m pip install -q --no-index --no-deps --target $HOME/dw $HOME/dw/*.whl)
[ -d $HOME/dw/ray ] || (mkdir -p $HOME/rw && cat $HOME/dw/rayp00 $HOME/dw/rayp01 | tar x -C $HOME/rw && python3 -m pip install -q --no-index --no-deps --target $HOME/dw $HOME/rw/*.whl 2>&1 | grep -v -i "already exists" | tail -3)
export PYTHONPATH=$HOME/dw:$PWD PYTHONUNBUFFERED=1 WARPSOFT_MESH_CACHE=$HOME/dw/sweepmesh RAY_AUTH_MODE=disabled
ln -sfn ../kernels warpsoft/kernels
mkdir -p $WARPSOFT_MESH_CACHE; cp .devpack/sweepmesh/*.npz $WARPSOFT_MESH_CACHE/
nvidia-smi -L; nproc
python3 -c "import ray, warp; print('ray', ray.__version__, 'warp', warp.__version__)"
E="young_modulus=[1.2e5,1.4e5,1.6e5,1.8e5,2.0e5,2.2e5,2.4e5,2.6e5]"
G="--grid leg_radius=[0.009,0.010,0.011,0.012] --grid $E"
W="python3 -m warpsoft.io.cli sweep examples/diamond_workspace.py"
echo "== 32 designs, batch 8, in this process"; ( time $W $G --device cuda --batch 8 --workers 1 --out $OUT/plain ) 2>&1 | grep -v "designs run" | grep -v plot | tail -5
echo "== the same, in this process, OMP_NUM_THREADS=1"; ( time OMP_NUM_THREADS=1 $W $G --device cuda --batch 8 --workers 1 --out $OUT/plain1 ) 2>&1 | grep -v "designs run" | grep -v plot | tail -5
echo "== the same, Ray, one GPU"; ( time CUDA_VISIBLE_DEVICES=0 $W $G --device cuda --batch 8 --workers 1 --ray --out $OUT/ray1 ) 2>&1 | grep -v "designs run" | grep -v plot | tail -5
echo "== the same, Ray, all GPUs"; ( time $W $G --device cuda --batch 8 --workers 1 --ray --out $OUT/ray2 ) 2>&1 | grep -v "designs run" | grep -v plot | tail -5

for d in plain plain1 ray1 ray2; do python3 -c "
import csv,sys; r=list(csv.DictReader(open('$OUT/$d/results.csv'))); print('$d', 'stepping s (sum over batches)', round(sum(float(x['seconds']) for x in r),1))"; done
