// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The shading point's random numbers: hashes of P (Cycles' pixel jitter changes P with every
// render sample) and the seed, in streams that never overlap, and the stratified sequences
// drawn from them (docs/model.md "Environment sampling (reference mode)").

#ifndef CT_RANDOM_H
#define CT_RANDOM_H

// The largest float below 1: every uniform number lies in [0, U_MAX].
#define U_MAX 0.99999994

// The streams of one shading point: hashnoise(key, stream + i) for i below the next stream.
#define STREAM_REFERENCE 0.5          // +0..3: the reference integrator's rotations
#define STREAM_REFERENCE_PICK 10.5    // +i: sample i's lobe choice, or environment column
#define STREAM_REFERENCE_ENV 5000.5   // +i: environment sample i's fourth number
#define STREAM_LIGHTS 20000.5         // +8 slot + k: light slot's five numbers (k < 5)
#define STREAM_RESIDUAL 30000.5       // +0, 1: the residual albedo's rotations
#define STREAM_CORRECTION 40000.5     // the correction's technique rotation
#define STREAM_CORRECTION_SAMPLES 40001.5  // +8 s + k: correction sample s's numbers (k < 5)

// The key of a shading point's streams.
point shading_key(point P, int seed)
{
    return P * 1000.0 + vector(seed * 7.31, seed * 3.17, seed * 1.13);
}

// A uniform number of a stream in [0, U_MAX].
float uniform01(point key, float stream) { return min(hashnoise(key, stream), U_MAX); }

float wrap01(float x) { return x - floor(x); }

// Van der Corput radical inverse in base 2, for a stratified point set per shading point.
float radical_inverse2(int i)
{
    int bits = i;
    float r = 0.0, f = 0.5;
    while (bits > 0) {
        if (bits & 1)
            r += f;
        bits = bits >> 1;
        f *= 0.5;
    }
    return r;
}

#endif // CT_RANDOM_H
