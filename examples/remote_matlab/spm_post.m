function [answer, status] = spm_post(base_url, resource, body)
%SPM_POST  POST a JSON body to a resource of an spm-pin server.
%   [verdict, status] = spm_post('http://127.0.0.1:8750', '/check', ...
%                                struct('theta_deg', [60 90 220]))
%
%   See spm_request for how MATLAB and GNU Octave send the body.
  [answer, status] = spm_request('POST', base_url, resource, body);
end
