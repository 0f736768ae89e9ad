import cupy as cp, numpy as np, json, sys
from cupyx.profiler import benchmark
R=300; n=2**20
def smooth7_below(m):
    best=0
    p2=1
    while p2<=m:
        p3=p2
        while p3<=m:
            p5=p3
            while p5<=m:
                p7=p5
                while p7<=m:
                    best=max(best,p7); p7*=7
                p5*=5
            p3*=3
        p2*=2
    return best
def smooth5_below(m):
    best=0;p2=1
    while p2<=m:
        p3=p2
        while p3<=m:
            p5=p3
            while p5<=m:
                best=max(best,p5); p5*=5
            p3*=3
        p2*=2
    return best
res={}
def t(name,f,*a):
    r=benchmark(f,a,n_repeat=20,n_warmup=3)
    ms=float(np.median(r.gpu_times))*1e3
    res[name]=ms; print(f"{name:50s} {ms:8.3f} ms",flush=True)
x=cp.random.standard_normal((R,n))
y=cp.empty_like(x)
t("copy 300x2^20 f64 (d2d)", lambda a: y.__setitem__(Ellipsis,a), x)
print("copy GB/s", 2*x.nbytes/res["copy 300x2^20 f64 (d2d)"]/1e6)
X=cp.fft.rfft(x,axis=-1)
t("irfft 300x2^20", lambda a: cp.fft.irfft(a,n=n,axis=-1), X)
t("rfft 300x2^20", lambda a: cp.fft.rfft(a,axis=-1), x)
for m in (1046492, smooth7_below(1046492), smooth5_below(1046492), 1045440, 2**20 - 2**14):
    xs=x[:, :m].copy()
    t(f"rfft 300x{m}", lambda a: cp.fft.rfft(a,axis=-1), xs)
print("7-smooth", smooth7_below(1046492), "5-smooth", smooth5_below(1046492))
t("cumsum axis1 300x2^20", lambda a: cp.cumsum(a,axis=1), x)
t("sum axis1", lambda a: a.sum(axis=1), x)
t("mean/var rows(300 x 2^19 complex) psd moments", lambda a: (cp.abs(a)**2).mean(axis=0), X)
t("min/max axis1", lambda a: (a.min(axis=1), a.max(axis=1)), x)
json.dump(res, open(sys.argv[1],"w"), indent=1)
